// E3 (lidar-physics.md "Signal-dependent range bias (range walk)"): threshold timing fires earlier
// on strong pulses, and SPAD pile-up skews the histogram early at high flux, so bright returns read
// short:
//   bias += -walk * log10(max(S, S0) / S0)      (S: radiometry's expected SIGNAL, photons)
//   bias += retro_offset                         (on retroreflective surfaces)
// The vendor states zero bias for Lambertian targets and a slight one for retroreflectors [S1];
// no numbers are published, so both terms are off (0) unless a profile or a fit sets them.
#include <algorithm>
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct RangeWalkParameters {
  double walk_m = 0.0;               // per decade of signal above the reference
  double reference_photons = 100.0;  // S0: no walk at or below it
  double retro_offset_m = 0.0;
};

class RangeWalk final : public TabledEffect<RangeWalk, RangeWalkParameters> {
 public:
  using P = RangeWalkParameters;
  static constexpr std::string_view kName = "range_walk";
  static constexpr std::array<ParameterSpec<P>, 3> kSpecs{{
      {"walk_m", &P::walk_m, {-1.0, 1.0}},
      {"reference_photons", &P::reference_photons, {1.0, 1e6}},
      {"retro_offset_m", &P::retro_offset_m, {-1.0, 1.0}},
  }};
  using TabledEffect::TabledEffect;

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext&, MeasuredColumn& measured) const override {
    float* range = measured.range_m.data();
    for (size_t beam = 0; beam < ideal.size(); ++beam) {
      if (range[beam] == 0.0f) continue;
      range[beam] = static_cast<float>(static_cast<double>(range[beam]) +
                                       bias(measured.signal_photons[beam], ideal[beam].retroreflective != 0));
    }
  }

  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    prediction.bias_m += bias(prediction.signal_photons, ideal.retroreflective != 0);
  }

 private:
  double bias(double signal, bool retro) const {
    const double s0 = params().reference_photons;
    return -params().walk_m * std::log10(std::max(signal, s0) / s0) + (retro ? params().retro_offset_m : 0.0);
  }
};

}  // namespace

std::unique_ptr<Effect> make_range_walk(const nlohmann::json& params, const Location& at) {
  return RangeWalk::create(params, at);
}

// A pixel's temporal mean carries a walk, which does not change between frames.
EffectCard range_walk_card() {
  return {.catalogue = "E3",
          .candidate = true,
          .fit = {{"walk_m", 0.0, 0.005}, {"retro_offset_m", 0.0, 0.01}},
          .seen_against_temporal_mean = false};
}

}  // namespace lidartwin::effects_detail
