// Photon (shot) noise on the reported SIGNAL and NEAR_IR (lidar-physics.md 2.1/2.2): both are
// photon counts, Poisson to first order. SIGNAL is the return's peak with the background taken
// off, so its variance is that of both, F (S + B); NEAR_IR, the background alone, varies by F B.
// F is the excess-noise factor (1 for pure Poisson counting; SPAD dead time and the histogram's
// processing change it: fit it from a static recording's frame-to-frame SIGNAL spread). The draws
// are Gaussian with those variances, clamped at 0 (accurate above a few tens of photons; below,
// the clamp raises the mean slightly). REFLECTIVITY, which the sensor computes from SIGNAL,
// follows it in its linear band. Place it after every effect that reads SIGNAL (signal_precision,
// range_walk, window, dropout): those model the expected signal, as predict does.
#include <algorithm>
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct ShotNoiseParameters {
  double excess_noise_factor = 1.0;  // F
};

class ShotNoise final : public TabledEffect<ShotNoise, ShotNoiseParameters> {
 public:
  using P = ShotNoiseParameters;
  static constexpr std::string_view kName = "shot_noise";
  static constexpr std::array<ParameterSpec<P>, 1> kSpecs{{
      {"excess_noise_factor", &P::excess_noise_factor, {0.0, 20.0}},
  }};
  using TabledEffect::TabledEffect;

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    const double f = params().excess_noise_factor;
    if (f <= 0.0) return;
    const ColumnStreams streams = column_streams(context);
    for (uint32_t beam = 0; beam < measured.size(); ++beam) {
      const RandomStream stream = streams(beam);
      const double b = measured.near_ir_photons[beam];
      noisy_return(stream, 0, f, b, measured.signal_photons[beam], measured.reflectivity[beam]);
      noisy_return(stream, 2, f, b, measured.signal2_photons[beam], measured.reflectivity2[beam]);
      measured.near_ir_photons[beam] = clamped(b + std::sqrt(f * b) * stream.normal_ziggurat(1));
    }
  }

  void predict(const IdealReturn&, const ColumnContext&, Prediction& prediction) const override {
    const double f = params().excess_noise_factor;
    prediction.signal_variance += f * (prediction.signal_photons + prediction.near_ir_photons);
    prediction.near_ir_variance += f * prediction.near_ir_photons;
  }

 private:
  static float clamped(double photons) { return static_cast<float>(std::max(0.0, photons)); }

  // A return's SIGNAL (0 = no return: left alone, and no draw made) and the REFLECTIVITY computed
  // from it; the normal comes from draw pair `pair` of the pixel's stream.
  static void noisy_return(const RandomStream& stream, uint32_t pair, double f, double b, float& signal,
                           float& reflectivity) {
    if (signal <= 0.0f) return;
    const double s = signal;
    const float noisy = clamped(s + std::sqrt(f * (s + b)) * stream.normal_ziggurat(pair));
    if (reflectivity <= 100.0f) reflectivity = static_cast<float>(static_cast<double>(reflectivity * noisy) / s);
    signal = noisy;
  }
};

}  // namespace

std::unique_ptr<Effect> make_shot_noise(const nlohmann::json& params, const Location& at) {
  return ShotNoise::create(params, at);
}

EffectCard shot_noise_card() {
  return {.catalogue = "", .note = "no catalogue id: lidar-physics.md 2.2, photon noise of SIGNAL and NEAR_IR"};
}

}  // namespace lidartwin::effects_detail
