// E16 (lidar-physics.md "Window, near-range and blockage artifacts"): dirt, water or a partial
// blockage on the window over one azimuth sector. In the sector:
//   - the window transmits `transmission` of the returning light: SIGNAL is multiplied by it, and
//     so is the calibrated REFLECTIVITY in its linear band (the sensor derives it from SIGNAL and
//     range; the retroreflector band above 100 is left as it was). Detection follows when dropout
//     (E5) comes later in the chain: place `window` after radiometry and before dropout.
//   - with probability `near_return_probability` the dirt itself returns light at
//     `near_return_range_m` with `near_return_signal_photons`. Returns are ordered strongest first
//     (return_order STRONGEST_TO_WEAKEST, the default [S11]): the near return is the first return
//     when it is stronger than the surface's (or there is none), and the second otherwise (DUAL
//     profiles; single-return profiles carry only the first). range_limits, later in the chain,
//     drops it below the sensor's minimum range, as the firmware does.
// The sector is in encoder angle, as the column headers report it: measurement id m of W columns
// sits at 360 m / W degrees; it starts at `sector_start_deg` and spans `sector_width_deg`
// (wrapping past 360). No published magnitudes: the defaults (a 30-degree sector at half
// transmission, no near returns) are an example to edit, not a sourced value.
#include <cmath>

#include "effects/attenuation.h"
#include "effects/builtin_effects.h"
#include "effects/extra_return.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct WindowParameters {
  double sector_start_deg = 0.0;
  double sector_width_deg = 30.0;
  double transmission = 0.5;  // factor on SIGNAL inside the sector
  double near_return_probability = 0.0;
  double near_return_range_m = 0.05;
  double near_return_signal_photons = 20.0;
};

class Window final : public TabledEffect<Window, WindowParameters> {
 public:
  using P = WindowParameters;
  static constexpr std::string_view kName = "window";
  static constexpr std::array<ParameterSpec<P>, 6> kSpecs{{
      {"sector_start_deg", &P::sector_start_deg, {0.0, 360.0}},
      {"sector_width_deg", &P::sector_width_deg, {0.0, 360.0}},
      {"transmission", &P::transmission, {0.0, 1.0}},
      {"near_return_probability", &P::near_return_probability, {0.0, 1.0}},
      {"near_return_range_m", &P::near_return_range_m, {0.0, 2.0}},
      {"near_return_signal_photons", &P::near_return_signal_photons, {0.0, 1e5}},
  }};
  using TabledEffect::TabledEffect;

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  bool in_sector(const ColumnContext& context) const {
    const double offset = std::fmod(context.encoder_angle_deg() - params().sector_start_deg + 360.0, 360.0);
    return offset < params().sector_width_deg;
  }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    if (!in_sector(context)) return;
    const auto tau = static_cast<float>(params().transmission);
    for (size_t beam = 0; beam < measured.size(); ++beam) attenuate(measured, beam, tau);
    if (params().near_return_probability <= 0.0) return;
    const ColumnStreams streams = column_streams(context);
    const auto near_range = static_cast<float>(params().near_return_range_m);
    const auto near_signal = static_cast<float>(params().near_return_signal_photons);
    for (uint32_t beam = 0; beam < measured.size(); ++beam) {
      if (streams(beam).uniform(0) < params().near_return_probability) {
        add_return(measured, beam, near_range, near_signal);
      }
    }
  }

  void predict(const IdealReturn& ideal, const ColumnContext& context, Prediction& prediction) const override {
    if (!in_sector(context)) return;
    prediction.signal_photons *= params().transmission;
    predict_added_return(prediction, ideal.hit(), params().near_return_probability,
                         params().near_return_signal_photons);
  }
};

}  // namespace

std::unique_ptr<Effect> make_window(const nlohmann::json& params, const Location& at) {
  return Window::create(params, at);
}

EffectCard window_card() {
  return {.catalogue = "E16", .note = "E16's window part: dirt, water or blockage on the window"};
}

}  // namespace lidartwin::effects_detail
