// E8 (lidar-physics.md "Retroreflector blooming, halo, saturation"): a retroreflector returns
// orders of magnitude more light than the surfaces around it, and its stray light fires the
// detectors of the beams beside it. All beams of a column fire at once, so the halo runs along the
// column: a pixel d rows from a retroreflective hit (d <= IdealReturn::kRetroReachRows, the
// caster's retro_rows), itself not one, with weight w = exp(-(d - 1) / decay_rows):
//   - loses its own returns with probability dropout_probability * w (the saturated ring: the
//     "abnormally missing" points beside reflective stripes, [S35]);
//   - then, with probability probability * w, gains a halo return at the retroreflector's range
//     plus N(0, range_sigma_m), with signal_photons, placed by strength as the sensor orders its
//     returns (first when stronger than the surface's or where nothing returned, second otherwise;
//     the noise around road furniture that disappears when it is covered, [S34]).
// The halo's SIGNAL is a fixed count rather than a fraction of the retroreflector's, so predict
// needs nothing but the pixel and its retro neighbour. The document found no numeric halo
// parameters for Ouster ("fit them"): the defaults are an example to edit, not a sourced value.
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/extra_return.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct HaloParameters {
  double probability = 0.3;  // of a halo return one row from the retroreflector
  double decay_rows = 1.5;
  double range_sigma_m = 0.02;
  double signal_photons = 30.0;
  double dropout_probability = 0.0;  // of losing the own returns one row from the retroreflector
};

class Halo final : public TabledEffect<Halo, HaloParameters> {
 public:
  using P = HaloParameters;
  static constexpr std::string_view kName = "halo";
  static constexpr std::array<ParameterSpec<P>, 5> kSpecs{{
      {"probability", &P::probability, {0.0, 1.0}},
      {"decay_rows", &P::decay_rows, {0.1, 20.0}},
      {"range_sigma_m", &P::range_sigma_m, {0.0, 1.0}},
      {"signal_photons", &P::signal_photons, {0.0, 1e5}},
      {"dropout_probability", &P::dropout_probability, {0.0, 1.0}},
  }};
  explicit Halo(const P& p) : TabledEffect(p) {
    for (int d = 1; d <= IdealReturn::kRetroReachRows; ++d) {
      weight_[static_cast<size_t>(d)] = std::exp(-(d - 1) / p.decay_rows);
    }
  }

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    const auto sigma = static_cast<float>(params().range_sigma_m);
    const auto signal = static_cast<float>(params().signal_photons);
    for (uint32_t beam = 0; beam < ideal.size(); ++beam) {
      const IdealReturn& pixel = ideal[beam];
      if (pixel.retro_rows == 0) continue;
      const double w = weight_[pixel.retro_rows];
      const RandomStream s = streams(beam);
      if (s.uniform(0) < params().dropout_probability * w) lose_returns(measured, beam);
      if (s.uniform(1) < params().probability * w) {
        const float range = pixel.retro_range_m + sigma * static_cast<float>(s.normal_ziggurat(1));
        add_return(measured, beam, std::max(range, 0.001f), signal);
      }
    }
  }

  // The halo return is narrow (range_sigma_m about the retroreflector's range): a partner
  // component of the mixture where it comes first (extra_return.h).
  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    if (ideal.retro_rows == 0) return;
    const double w = weight_[ideal.retro_rows];
    lose_returns(prediction, params().dropout_probability * w);
    predict_added_return_at(prediction, ideal, params().probability * w, params().signal_photons,
                            static_cast<double>(ideal.retro_range_m), params().range_sigma_m);
  }

 private:
  static void lose_returns(MeasuredColumn& measured, uint32_t beam) {
    measured.range_m[beam] = measured.signal_photons[beam] = measured.reflectivity[beam] = 0.0f;
    measured.range2_m[beam] = measured.signal2_photons[beam] = measured.reflectivity2[beam] = 0.0f;
  }
  static void lose_returns(Prediction& prediction, double q) {
    prediction.p_detect *= 1.0 - q;
    prediction.p_second *= 1.0 - q;
  }

  std::array<double, IdealReturn::kRetroReachRows + 1> weight_{};  // [rows away]
};

}  // namespace

std::unique_ptr<Effect> make_halo(const nlohmann::json& params, const Location& at) { return Halo::create(params, at); }

// The halo's reach (decay_rows) and its returns' spread and strength stay at their defaults: its
// rates beside the retroreflectors are what the likelihood sees most clearly, and without a scene
// the retroreflectors are unknown.
EffectCard halo_card() {
  return {.catalogue = "E8",
          .candidate = true,
          .fit = {{"probability", 0.1, 0.05}, {"dropout_probability", 0.0, 0.05}},
          .seen_against_temporal_mean = false};
}

}  // namespace lidartwin::effects_detail
