// The signal channel's parameter misfit (lidar-physics.md 2.2, "Calibrating g(r) and K"): a capture
// from another unit, firmware or generator has its own product gain K and near-field overlap g(r).
// The range likelihood hardly sees them, yet every signal-driven effect (E2, E3, E5, E8, E14) is
// judged against the expected signal they make: so they are refitted first, on the SIGNAL channel.
// The model: the profile's expected signal m times c g'(r) / g(r), with g' = 1 / (1 + (r0'/r)^p')
// and K' = c K. Fitted by Poisson quasi-likelihood (the photon count's own law, and unbiased for
// any noise whose mean is right, where least squares in ln S would be pulled down by 1/(2S)); c is
// profiled out in closed form, r0' and p' by NLopt; the dispersion (Pearson chi-square / dof)
// scales the likelihood ratio and the intervals, so a SIGNAL that is not Poisson is judged fairly.
// The pixels: returns within 5 sigma of their surface (a mixed or halo return carries another
// surface's signal; at a depth edge, what is expected is the own echo's), off retroreflectors
// (their own rho_app), below the 16-bit ceiling, and with an expected signal of at least 10
// photons; chosen by the prediction, never by the measured signal, which would select the noise.
// The ambient level (NEAR_IR = ambient x rho) is refitted beside them by least squares: E2's
// variance and E5's threshold read it. Pixels the wire's ceiling may clip (RNG15's NEAR_IR ends at
// 4080) are left out of both.
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Dense>
#include <nlopt.hpp>

#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/pixel_likelihood.h"

namespace lidartwin {
namespace {

constexpr double kMinExpectedSignal = 10.0;
constexpr float kSignalCeiling = 65535.0f;
// A refit that moves a channel's expectation by less than this (RMS over the pixels, in ln) is left
// alone however significant: with a deterministic SIGNAL channel (the shipped profiles leave shot
// noise off) the least rounding would otherwise "misfit".
constexpr double kMinChange = 0.02;

struct SignalPixel {
  double range_m;
  double expected;  // the profile's expected signal
  double measured;
};

double log_overlap(double r, double r0, double p) { return r0 > 0.0 ? -std::log1p(std::pow(r0 / r, p)) : 0.0; }

struct OverlapFit {
  const std::vector<SignalPixel>* pixels;
  double r0 = 0.0, p = 0.0;  // the profile's
  double sum_measured = 0.0;
  // ln of the overlap's change g'(r) / g(r) at a pixel.
  double log_change(const SignalPixel& s, double r0_new, double p_new) const {
    return log_overlap(s.range_m, r0_new, p_new) - log_overlap(s.range_m, r0, p);
  }
  // c, profiled out: the fitted counts sum to the measured ones.
  double gain_ratio(double r0_new, double p_new) const {
    double sum = 0.0;
    for (const SignalPixel& s : *pixels) sum += s.expected * std::exp(log_change(s, r0_new, p_new));
    return sum_measured / sum;
  }
  // The Poisson deviance at (c, r0', p').
  double deviance(double c, double r0_new, double p_new) const {
    double d = 0.0;
    for (const SignalPixel& s : *pixels) {
      const double mu = c * s.expected * std::exp(log_change(s, r0_new, p_new));
      d += s.measured * std::log(s.measured / mu) - (s.measured - mu);
    }
    return 2.0 * d;
  }
  double profiled_deviance(double r0_new, double p_new) const {
    return deviance(gain_ratio(r0_new, p_new), r0_new, p_new);
  }
};

}  // namespace

std::optional<ParameterMisfit> refit_radiometry(const PixelTable& t, const EffectChain& chain,
                                                const DiagnoseOptions& options) {
  const auto& effects = chain.effects();
  const auto found =
      std::find_if(effects.begin(), effects.end(), [](const auto& e) { return e->name() == "radiometry"; });
  if (found == effects.end()) return std::nullopt;
  const size_t index = static_cast<size_t>(found - effects.begin());
  const nlohmann::json before = (*found)->to_json();
  const auto value_of = [&](const char* name) {
    for (const EffectParameter& p : (*found)->parameters())
      if (p.name == name) return p;
    throw std::logic_error(std::string("radiometry has no parameter ") + name);
  };
  const EffectParameter gain = value_of("gain_photons_m2"), r0 = value_of("overlap_range_m"),
                        exponent = value_of("overlap_exponent"), ambient = value_of("ambient_photons");

  std::vector<SignalPixel> pixels;
  // NEAR_IR: sums of predicted, predicted^2, measured x predicted, measured^2
  double nir_p = 0.0, nir_pp = 0.0, nir_mp = 0.0, nir_mm = 0.0;
  size_t nir_pixels = 0;
  const size_t stride = std::max<size_t>(1, t.size() / std::max<size_t>(options.max_pixels, 1));
  for (size_t i = 0; i < t.size(); i += stride) {
    if (t.ideal_range_m[i] <= 0.0f) continue;
    const Prediction p = chain.predict(t.ideal_of(i), t.context_of(i));
    // A channel at the wire's ceiling reads the ceiling, not the photons: pixels whose prediction
    // comes within 5 sd of it are left out (by the prediction, so that the noise selects nothing).
    const auto below_ceiling = [](double expected, double variance, float ceiling) {
      return expected + 5.0 * std::sqrt(std::max(variance, 0.0)) < static_cast<double>(ceiling);
    };
    // (predicted at two of the wire's steps or more, a reading of 0 is a channel an OSF file left
    // out, not a rounding: those are dropped without choosing by the noise)
    if (t.near_ir[i] > 0.0f && p.near_ir_photons >= 2.0 * static_cast<double>(t.context.near_ir_step) &&
        below_ceiling(p.near_ir_photons, p.near_ir_variance, t.context.max_wire_near_ir)) {
      const double b = static_cast<double>(t.near_ir[i]);
      nir_p += p.near_ir_photons;
      nir_pp += p.near_ir_photons * p.near_ir_photons;
      nir_mp += b * p.near_ir_photons;
      nir_mm += b * b;
      ++nir_pixels;
    }
    if (t.range_m[i] <= 0.0f || t.retro[i] == 0) continue;
    if (t.signal[i] <= 0.0f || t.signal[i] >= kSignalCeiling || p.signal_photons < kMinExpectedSignal) continue;
    const double e = static_cast<double>(t.range_m[i] - t.ideal_range_m[i]) - p.bias_m;
    if (e * e > 25.0 * p.variance_m2 + 1e-4) continue;
    // At a depth edge (E6's echoes) a return on the pixel's own surface is its own echo, with that
    // echo's signal: less than the mean over both, which the partner's echo raises where it wins.
    double expected = p.signal_photons;
    if (p.echo_count > 0) {
      double weight = 0.0, signal = 0.0;
      for (size_t k = 0; k < p.own_echoes; ++k) {
        weight += static_cast<double>(p.echoes[k].weight);
        signal += static_cast<double>(p.echoes[k].weight) * static_cast<double>(p.echoes[k].signal_factor);
      }
      if (weight <= 0.0) continue;
      expected *= signal / weight;
    }
    if (expected < kMinExpectedSignal || !below_ceiling(expected, p.signal_variance, t.context.max_wire_signal))
      continue;
    pixels.push_back({static_cast<double>(t.ideal_range_m[i]), expected, static_cast<double>(t.signal[i])});
  }

  ParameterMisfit m;
  m.channel = "signal";
  m.index = index;
  Candidate& c = m.refit;
  c.effect = "radiometry";
  c.catalogue = effect_catalogue("radiometry").value_or("");
  c.effect_json = before;
  double k = 0.0, penalty = 0.0;
  // A part is kept when its likelihood ratio is significant and it moves its channel by 2 % or more.
  const auto keep = [&](double delta_nll, double n, double parameters, double change) {
    const double delta_bic = 2.0 * delta_nll - parameters * std::log(n);
    if (change < kMinChange || delta_bic < options.min_delta_bic ||
        1.0 - chi2_cdf(2.0 * delta_nll, parameters) > options.alpha)
      return false;
    c.delta_nll += delta_nll;
    k += parameters;
    penalty += parameters * std::log(n);
    return true;
  };

  // SIGNAL: the gain and the overlap.
  if (pixels.size() >= 100) {
    const double n = static_cast<double>(pixels.size());
    OverlapFit fit{&pixels, r0.value, exponent.value};
    for (const SignalPixel& s : pixels) fit.sum_measured += s.measured;
    const double d0 = fit.deviance(1.0, r0.value, exponent.value);
    std::vector<double> x{r0.value, exponent.value};
    nlopt::opt opt(nlopt::LN_BOBYQA, 2);
    opt.set_lower_bounds({r0.lower, exponent.lower});
    opt.set_upper_bounds({r0.upper, exponent.upper});
    opt.set_initial_step({std::max(0.2 * r0.value, 0.5), 0.3});
    opt.set_xtol_rel(1e-6);
    opt.set_maxeval(400);
    opt.set_min_objective([](const std::vector<double>& v, std::vector<double>&,
                             void* d) { return static_cast<const OverlapFit*>(d)->profiled_deviance(v[0], v[1]); },
                          &fit);
    double d1 = d0;
    try {
      opt.optimize(x, d1);
    } catch (const std::exception&) {  // a roundoff-limited stop keeps the best point found
    }
    const double c_ratio = fit.gain_ratio(x[0], x[1]);
    d1 = fit.deviance(c_ratio, x[0], x[1]);
    // The dispersion, the information (sum of mu j j' with j the gradient of ln mu in (ln c, r0', p'))
    // and how far the expected signal moves.
    double pearson = 0.0, change2 = 0.0;
    Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
    const double h0 = std::max(1e-4 * x[0], 1e-6), h1 = std::max(1e-4 * x[1], 1e-6);
    for (const SignalPixel& s : pixels) {
      const double lg = log_overlap(s.range_m, x[0], x[1]);
      const double ln_change = std::log(c_ratio) + fit.log_change(s, x[0], x[1]);
      const double mu = s.expected * std::exp(ln_change);
      pearson += (s.measured - mu) * (s.measured - mu) / mu;
      change2 += ln_change * ln_change;
      const Eigen::Vector3d j{1.0, (log_overlap(s.range_m, x[0] + h0, x[1]) - lg) / h0,
                              (log_overlap(s.range_m, x[0], x[1] + h1) - lg) / h1};
      information += mu * j * j.transpose();
    }
    const double dispersion = std::max(pearson / (n - 3.0), 1e-12);
    // The quasi-likelihood ratio.
    if (keep((d0 - d1) / (2.0 * dispersion), n, 3.0, std::sqrt(change2 / n))) {
      const Eigen::Matrix3d covariance = dispersion * information.inverse();
      const auto half = [&](int j) {
        const double v = covariance(j, j);
        return std::isfinite(v) && v >= 0.0 ? 1.96 * std::sqrt(v) : std::numeric_limits<double>::infinity();
      };
      const double new_gain = std::clamp(gain.value * c_ratio, gain.lower, gain.upper);
      c.params.push_back({"gain_photons_m2", new_gain, new_gain * std::exp(-half(0)), new_gain * std::exp(half(0))});
      c.params.push_back(
          {"overlap_range_m", x[0], std::max(r0.lower, x[0] - half(1)), std::min(r0.upper, x[0] + half(1))});
      c.params.push_back({"overlap_exponent", x[1], std::max(exponent.lower, x[1] - half(2)),
                          std::min(exponent.upper, x[1] + half(2))});
    }
  }

  // NEAR_IR: the ambient level, NEAR_IR = ambient x rho, a ratio by least squares.
  if (nir_pixels >= 100 && nir_pp > 0.0) {
    const double ratio = nir_mp / nir_pp;
    // The wire rounds NEAR_IR to its step (RNG15's 16 photons): each pixel's reading is off by up to
    // a step, which moves the ratio by up to step sum(p) / sum(p^2) with nothing wrong (the paper
    // profiles' ambient of 100 photons reads 0-96 there). A change within that is not a misfit.
    const double rounding = static_cast<double>(t.context.near_ir_step) * nir_p / nir_pp;
    const double rss0 = nir_mm - 2.0 * nir_mp + nir_pp, rss1 = nir_mm - ratio * nir_mp;
    // Gaussian residuals with their variance profiled out: the likelihood ratio is (n/2) ln(RSS0/RSS1).
    const double n = static_cast<double>(nir_pixels);
    if (keep(0.5 * n * std::log(rss0 / std::max(rss1, 1e-300)), n, 1.0,
             std::abs(std::log(std::max(ratio, 1e-12))) - rounding)) {
      const double se = std::sqrt(rss1 / (n - 1.0) / nir_pp);
      const double value = std::clamp(ambient.value * ratio, ambient.lower, ambient.upper);
      c.params.push_back(
          {"ambient_photons", value, ambient.value * (ratio - 1.96 * se), ambient.value * (ratio + 1.96 * se)});
    }
  }
  if (c.params.empty()) return std::nullopt;
  c.delta_bic = 2.0 * c.delta_nll - penalty;
  c.p_value = 1.0 - chi2_cdf(2.0 * c.delta_nll, k);
  for (const FittedParameter& p : c.params) {
    c.effect_json[p.name] = p.value;
    m.old_values.emplace_back(p.name, value_of(p.name.c_str()).value);
  }
  return m;
}

}  // namespace lidartwin
