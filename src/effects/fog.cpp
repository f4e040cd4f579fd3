// E13 (lidar-physics.md "Atmosphere: attenuation and volume backscatter"): fog, dust or rain
// between the sensor and the scene.
//   - Two-way Beer-Lambert extinction: SIGNAL (and the calibrated REFLECTIVITY the sensor derives
//     from it, in its linear band) falls by exp(-2 alpha r) at the surface's range r; dropout (E5)
//     placed after fog then loses the far, dark returns, faster with range than 1/r^2 would.
//   - Soft-target returns: with probability soft_return_probability the droplets themselves return
//     a peak before the surface (or in the sky, before max_range_m). Backscatter from range r' is
//     weighted by the two-way extinction exp(-2 alpha r'), so r' is drawn from that exponential,
//     truncated at the surface; with soft_signal_photons it is placed by strength with the
//     surface's return (extra_return.h): a second return in clear-enough air, the first in thick fog.
// alpha defaults to 0.06 per metre (meteorological optical range ln(20)/alpha = 50 m), the default
// of Hahner et al.'s fog simulation [S46]; Koschmieder's alpha = 3.912 / visibility gives the same
// scale. The soft-return rate and signal have no published Ouster values: 0.01 and 5 photons are
// an example to fit. The radiometry's own attenuation_per_m is clear air; this is the weather.
#include <cmath>

#include "effects/attenuation.h"
#include "effects/builtin_effects.h"
#include "effects/extra_return.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct FogParameters {
  double attenuation_per_m = 0.06;  // alpha
  double soft_return_probability = 0.01;
  double soft_signal_photons = 5.0;
  double max_range_m = 100.0;  // where the sky's soft returns end
};

class Fog final : public TabledEffect<Fog, FogParameters> {
 public:
  using P = FogParameters;
  static constexpr std::string_view kName = "fog";
  static constexpr std::array<ParameterSpec<P>, 4> kSpecs{{
      {"attenuation_per_m", &P::attenuation_per_m, {0.0, 1.0}},
      {"soft_return_probability", &P::soft_return_probability, {0.0, 1.0}},
      {"soft_signal_photons", &P::soft_signal_photons, {0.0, 1e5}},
      {"max_range_m", &P::max_range_m, {0.1, 10000.0}},
  }};
  using TabledEffect::TabledEffect;

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  double transmission(double range_m) const { return std::exp(-2.0 * params().attenuation_per_m * range_m); }

  // The range of a soft return: density proportional to exp(-2 alpha r') on (0, end], by inversion.
  double soft_range(double u, double end_m) const {
    const double k = 2.0 * params().attenuation_per_m;
    if (k * end_m < 1e-9) return u * end_m;  // clear air: uniform
    return -std::log1p(u * std::expm1(-k * end_m)) / k;
  }

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    for (size_t beam = 0; beam < measured.size(); ++beam) {
      if (!ideal[beam].hit()) continue;
      attenuate(measured, beam, static_cast<float>(transmission(ideal[beam].range_m)));
    }
    if (params().soft_return_probability <= 0.0) return;
    const ColumnStreams streams = column_streams(context);
    const auto signal = static_cast<float>(params().soft_signal_photons);
    for (uint32_t beam = 0; beam < measured.size(); ++beam) {
      const RandomStream stream = streams(beam);
      if (stream.uniform(0) >= params().soft_return_probability) continue;
      const double end_m = ideal[beam].hit() ? static_cast<double>(ideal[beam].range_m) : params().max_range_m;
      add_return(measured, beam, static_cast<float>(soft_range(stream.uniform(1), end_m)), signal);
    }
  }

  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    if (ideal.hit()) prediction.signal_photons *= transmission(ideal.range_m);
    predict_added_return(prediction, ideal.hit(), params().soft_return_probability, params().soft_signal_photons);
  }
};

}  // namespace

std::unique_ptr<Effect> make_fog(const nlohmann::json& params, const Location& at) { return Fog::create(params, at); }

EffectCard fog_card() { return {.catalogue = "E13"}; }

}  // namespace lidartwin::effects_detail
