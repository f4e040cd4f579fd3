// E6 (lidar-physics.md "Mixed pixels / beam divergence at depth discontinuities") and, in the dual
// profiles, the second return it gives (E15). Near a depth step a beam's footprint (Gaussian, FWHM
// gamma) straddles two surfaces: its own, at r_p, and its edge partner's, at r_q (the caster's
// choose_edge_partner: the neighbouring beam that hit across the step). The edge lies somewhere
// between the two beams' axes, at an angle delta from this beam's, uniform on (0, spacing): the cast
// knows only that it is between them. The share of the footprint beyond it is
//   w = Phi(-delta / sigma_b),  sigma_b = gamma / 2.355,
// and the two echoes carry P_p = (1 - w) a_p / r_p^2 and P_q = w a_q / r_q^2 (a = rho cos(theta);
// the near-field overlap g(r) is left out). Closer than a pulse length L they merge into one return
// at the power-weighted mean range (a "flying" point between the surfaces); farther apart the
// stronger is reported, and a dual profile reports the weaker as its second return when it carries
// at least second_fraction of the pixel's full power a_p / r_p^2. SIGNAL scales with the reported
// echo's share of that power. The range noise earlier effects added carries over to both returns.
// Defaults: gamma 0.13 degrees as E4 (the OS1-64 datasheet [S1]); L and second_fraction have no
// published value for Ouster [proposed]: fit them (lidartwin fit --add mixed_pixels).
// A footprint straddling the sky is not modelled (no partner: the beam keeps its range).
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <optional>

#include "effects/builtin_effects.h"
#include "effects/echo_quadrature.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

constexpr double kFwhmPerSigma = 2.3548200450309493;  // 2 sqrt(2 ln 2)
constexpr double kMinReflectance = 1e-6;              // a black surface still returns a little

double phi(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// The standard normal quantile: Acklam's rational approximation (relative error 1.15e-9), then one
// Halley step on Phi, which leaves it exact to double precision. p in (0, 1).
double phi_inverse(double p) {
  constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                          1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02, 6.680131188771972e+01,
                          -1.328068155111930e+01};
  constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                          -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00, 3.754408661907416e+00};
  constexpr double kLow = 0.02425;
  double x = 0.0;
  if (p < kLow || p > 1.0 - kLow) {
    const double q = std::sqrt(-2.0 * std::log(p < kLow ? p : 1.0 - p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
    if (p > 1.0 - kLow) x = -x;
  } else {
    const double q = p - 0.5, r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
  }
  const double e = phi(x) - p;
  const double u = e * std::sqrt(2.0 * 3.141592653589793) * std::exp(0.5 * x * x);
  return x - u / (1.0 + 0.5 * x * u);
}

struct MixedPixelsParameters {
  double divergence_rad = 0.13 * 3.141592653589793 / 180.0;
  double pulse_length_m = 1.0;
  double second_fraction = 0.1;
};

// One pixel's two echoes, as functions of the edge's angle delta from the beam's axis.
struct Straddle {
  double r_p, r_q;     // ranges of the pixel's surface and its partner's
  double full;         // a_p / r_p^2: the pixel's power with the whole footprint on its surface
  double partner;      // a_q / r_q^2
  double sigma_rad;    // the footprint's sigma
  double spacing_rad;  // delta is uniform on (0, spacing)
  bool merged;         // |r_q - r_p| < L: one return at the power-weighted mean

  double share_beyond(double delta) const { return phi(-delta / sigma_rad); }
  double power_p(double w) const { return (1.0 - w) * full; }
  double power_q(double w) const { return w * partner; }
  // The delta at which w = share (share in (0, 0.5]; w falls from 0.5 at delta = 0).
  double delta_at(double share) const {
    if (share >= 0.5) return 0.0;
    if (share <= 0.0) return spacing_rad;
    return std::min(-phi_inverse(share) * sigma_rad, spacing_rad);
  }
  // The probability that w lies in [lo, hi] (delta uniform; w decreasing in delta).
  double probability_w_in(double lo, double hi) const {
    if (hi < lo) return 0.0;
    return std::clamp((delta_at(lo) - delta_at(hi)) / spacing_rad, 0.0, 1.0);
  }
  // w above which the partner's echo is the stronger: w a_q / r_q^2 > (1 - w) a_p / r_p^2.
  double partner_wins_above() const { return full / (full + partner); }
};

// Gauss-Legendre nodes on (-1, 1), for 4 and 8 points (each symmetric pair listed once).
struct GaussLegendreNode {
  double x, weight;
};
GaussLegendreNode gauss_legendre(size_t points, size_t k) {
  static constexpr std::array<GaussLegendreNode, 2> four{
      {{0.3399810435848563, 0.6521451548625461}, {0.8611363115940526, 0.3478548451374538}}};
  static constexpr std::array<GaussLegendreNode, 4> eight{{{0.1834346424956498, 0.3626837833783620},
                                                           {0.5255324099163290, 0.3137066458778873},
                                                           {0.7966664774136267, 0.2223810344533745},
                                                           {0.9602898564975363, 0.1012285362903763}}};
  const size_t pair = k % (points / 2);
  const GaussLegendreNode n = points == 4 ? four[pair] : eight[pair];
  return k < points / 2 ? GaussLegendreNode{-n.x, n.weight} : n;
}

class MixedPixels final : public TabledEffect<MixedPixels, MixedPixelsParameters> {
 public:
  using P = MixedPixelsParameters;
  static constexpr std::string_view kName = "mixed_pixels";
  static constexpr std::array<ParameterSpec<P>, 3> kSpecs{{
      {"divergence_rad", &P::divergence_rad, {0.0, 0.05}},
      {"pulse_length_m", &P::pulse_length_m, {0.0, 50.0}},
      {"second_fraction", &P::second_fraction, {0.0, 1.0}},
  }};
  using TabledEffect::TabledEffect;

  bool needs_edge_partners() const override { return true; }

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    for (uint32_t beam = 0; beam < ideal.size(); ++beam) {
      const IdealReturn& in = ideal[beam];
      if (measured.range_m[beam] == 0.0f || !in.has_partner()) continue;
      const auto s = straddle(in);
      if (!s) continue;
      const double noise = static_cast<double>(measured.range_m[beam]) - s->r_p;
      const double w = s->share_beyond(streams(beam).uniform(0) * s->spacing_rad);
      const double p = s->power_p(w), q = s->power_q(w);
      const double signal = measured.signal_photons[beam];
      if (s->merged) {
        measured.range_m[beam] = static_cast<float>((p * s->r_p + q * s->r_q) / (p + q) + noise);
        measured.signal_photons[beam] = static_cast<float>(signal * (p + q) / s->full);
        continue;
      }
      const bool partner_first = q > p;
      const double strong = partner_first ? q : p, weak = partner_first ? p : q;
      measured.range_m[beam] = static_cast<float>((partner_first ? s->r_q : s->r_p) + noise);
      measured.signal_photons[beam] = static_cast<float>(signal * strong / s->full);
      if (weak / s->full >= params().second_fraction) {
        measured.range2_m[beam] = static_cast<float>((partner_first ? s->r_p : s->r_q) + noise);
        measured.signal2_photons[beam] = static_cast<float>(signal * weak / s->full);
        measured.reflectivity2[beam] = measured.reflectivity[beam];
      }
    }
  }

  // The edge's position delta, uniform on (0, spacing), by Gauss-Legendre nodes on each interval
  // where one echo is reported (Prediction::echoes): the effects after this one that read the
  // signal (dropout, E2) take their expectations over them, as their simulate sees each pixel's
  // draw. The moments here (the merged echo's mean and spread, the mean signal) are those nodes'.
  void predict(const IdealReturn& in, const ColumnContext&, Prediction& prediction) const override {
    if (!in.hit() || !in.has_partner()) return;
    const auto s = straddle(in);
    if (!s) return;
    const double step = s->r_q - s->r_p;
    std::array<Prediction::Echo, Prediction::kMaxEchoes> echoes{};
    size_t count = 0, own = 0;
    // Nodes on (a, b) of delta, each echo's signal relative to the pixel's whole footprint on its
    // own surface (signal_photons so far), and its range offset from that surface.
    const auto add_nodes = [&](double a, double b, size_t nodes, bool partner) {
      for (size_t k = 0; k < nodes; ++k) {
        const GaussLegendreNode node = gauss_legendre(nodes, k);
        const double delta = 0.5 * (a + b) + 0.5 * (b - a) * node.x;
        const double w = s->share_beyond(delta), p = s->power_p(w), q = s->power_q(w);
        Prediction::Echo& e = echoes[count++];
        e.weight = static_cast<float>(0.5 * (b - a) * node.weight / s->spacing_rad);
        if (s->merged) {
          e.signal_factor = static_cast<float>((p + q) / s->full);
          e.offset_m = static_cast<float>(step * q / (p + q));
        } else {
          e.signal_factor = static_cast<float>((partner ? q : p) / s->full);
          e.offset_m = static_cast<float>(partner ? step : 0.0);
        }
      }
    };
    // The partner's echo is the stronger (and reported) where w > partner_wins_above(), which is
    // at delta below delta_at(it) (w falls with delta); the pixel's own beyond.
    const double split = s->merged ? 0.0 : s->delta_at(std::nextafter(s->partner_wins_above(), 1.0));
    const bool partner_wins = split > 0.0, own_wins = split < s->spacing_rad;
    const size_t half = Prediction::kMaxEchoes / 2;
    if (own_wins) add_nodes(split, s->spacing_rad, partner_wins ? half : Prediction::kMaxEchoes, false);
    own = count;
    if (partner_wins) add_nodes(0.0, split, own_wins ? half : Prediction::kMaxEchoes, true);
    double gain = 0.0, partner = 0.0;
    for (size_t k = 0; k < count; ++k) {
      gain += static_cast<double>(echoes[k].weight) * static_cast<double>(echoes[k].signal_factor);
      if (k >= own) partner += static_cast<double>(echoes[k].weight);
    }
    for (size_t k = 0; k < count; ++k)
      echoes[k].signal_factor = static_cast<float>(static_cast<double>(echoes[k].signal_factor) / gain);
    prediction.signal_photons *= gain;
    prediction.echoes = echoes;
    prediction.echo_count = static_cast<uint8_t>(count);
    prediction.own_echoes = static_cast<uint8_t>(own);
    const OffsetMoments merged = own_offset_moments(prediction);
    prediction.bias_m += merged.mean;
    prediction.variance_m2 += merged.variance;
    if (s->merged) return;
    prediction.partner_mix = partner;
    prediction.partner_offset_m = step;
    prediction.partner_extra_variance_m2 = 0.0;  // the same Gaussian (a halo's before it is replaced)
    // Partner first: the pixel's echo second when (1 - w) >= fraction; pixel first: the partner's
    // second when w partner / full >= fraction.
    const double t = s->partner_wins_above();
    const double fraction = params().second_fraction;
    const double partner_second_from = fraction * s->full / s->partner;
    prediction.p_second = s->probability_w_in(std::nextafter(t, 1.0), std::min(0.5, 1.0 - fraction)) +
                          s->probability_w_in(std::max(partner_second_from, 0.0), std::min(t, 0.5));
  }

 private:
  std::optional<Straddle> straddle(const IdealReturn& in) const {
    const double sigma = params().divergence_rad / kFwhmPerSigma;
    if (sigma <= 0.0 || in.partner_spacing_rad <= 0.0f) return std::nullopt;
    const double r_p = in.range_m, r_q = in.partner_range_m;
    const double a_p = std::max(static_cast<double>(in.reflectivity * in.cos_incidence), kMinReflectance);
    const double a_q = std::max(static_cast<double>(in.partner_reflectance), kMinReflectance);
    return Straddle{r_p,
                    r_q,
                    a_p / (r_p * r_p),
                    a_q / (r_q * r_q),
                    sigma,
                    in.partner_spacing_rad,
                    std::abs(r_q - r_p) < params().pulse_length_m};
  }
};

}  // namespace

std::unique_ptr<Effect> make_mixed_pixels(const nlohmann::json& params, const Location& at) {
  return MixedPixels::create(params, at);
}

// The pulse length and the second return's threshold shape what a dual profile's RANGE2 shows,
// which the likelihood does not score yet: left at their defaults. Without a scene the edge
// partners are unknown.
EffectCard mixed_pixels_card() {
  return {.catalogue = "E6",
          .candidate = true,
          .fit = {{"divergence_rad", 0.002, 0.001}},
          .seen_against_temporal_mean = false};
}

}  // namespace lidartwin::effects_detail
