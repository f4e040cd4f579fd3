// E2 (lidar-physics.md "Signal/reflectivity-dependent precision"): timing jitter from photon
// statistics. With the expected signal S and ambient B (radiometry's SIGNAL and NEAR_IR, photons):
//   variance += floor^2 + k^2 (S + B) / S^2
// so a dark or oblique target (fewer photons) and sunlight (more ambient) both widen the spread,
// sigma ~ k / sqrt(S) where the signal dominates. No published Ouster value for k: off (k = 0)
// unless a profile or a fit sets it. S is floored at one photon (a return at all means one).
// Radiometry's channels are expected values (no shot noise), so simulate and predict read the
// same S and B.
#include <algorithm>
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/echo_quadrature.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct SignalPrecisionParameters {
  double k_m = 0.0;      // metres x sqrt(photons)
  double floor_m = 0.0;  // signal-independent part
};

class SignalPrecision final : public TabledEffect<SignalPrecision, SignalPrecisionParameters> {
 public:
  using P = SignalPrecisionParameters;
  static constexpr std::string_view kName = "signal_precision";
  static constexpr std::array<ParameterSpec<P>, 2> kSpecs{{
      {"k_m", &P::k_m, {0.0, 100.0}},
      {"floor_m", &P::floor_m, {0.0, 1.0}},
  }};
  using TabledEffect::TabledEffect;

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    float* range = measured.range_m.data();
    for (const uint32_t beam : measured.listed_returns()) {
      if (range[beam] == 0.0f) continue;
      const double sigma = std::sqrt(variance(measured.signal_photons[beam], measured.near_ir_photons[beam]));
      range[beam] = static_cast<float>(static_cast<double>(range[beam]) + sigma * streams(beam).normal_ziggurat(0));
    }
  }

  bool adds_returns() const override { return false; }

  // Where E6 splits the footprint, each echo's spread follows its own signal (echo_quadrature.h):
  // the own and the partner's components each take their echoes' mean variance.
  void predict(const IdealReturn&, const ColumnContext&, Prediction& prediction) const override {
    const double ambient = prediction.near_ir_photons;
    if (prediction.echo_count > 0) {
      const EchoMeans v = echo_means(prediction, [&](double signal) { return variance(signal, ambient); });
      prediction.variance_m2 += v.own;
      if (prediction.partner_mix > 0.0) prediction.partner_extra_variance_m2 += v.partner - v.own;
      return;
    }
    prediction.variance_m2 += variance(prediction.signal_photons, ambient);
  }

 private:
  double variance(double signal, double ambient) const {
    const double s = std::max(signal, 1.0);
    const double k = params().k_m;
    return params().floor_m * params().floor_m + k * k * (s + std::max(ambient, 0.0)) / (s * s);
  }
};

}  // namespace

std::unique_ptr<Effect> make_signal_precision(const nlohmann::json& params, const Location& at) {
  return SignalPrecision::create(params, at);
}

EffectCard signal_precision_card() { return {.catalogue = "E2", .candidate = true, .fit = {{"k_m", 0.05, 0.05}}}; }

}  // namespace lidartwin::effects_detail
