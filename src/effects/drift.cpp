// E12 (lidar-physics.md "Time / temperature drift"): a common-mode range offset that changes with
// time as the sensor warms up, plus a slow linear drift:
//   bias += offset + warmup_offset * exp(-t / warmup_time) + rate * t
// with t the column's time since the capture (or stream) began, which stands in for time since
// power-on: a capture does not say when the sensor was switched on. Vendor facts: about 12 minutes
// from cold start to "lasers at temperature" (OS0/OS1, [S8]), hence the default warm-up time of
// 4 minutes (three time constants in 12); no published offset magnitudes, so all offsets default
// to 0 (off).
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct DriftParameters {
  double offset_m = 0.0;         // mu_inf: after warm-up
  double warmup_offset_m = 0.0;  // mu_0 - mu_inf: at t = 0
  double warmup_time_s = 240.0;  // tau
  double rate_m_per_h = 0.0;     // linear drift
};

class Drift final : public TabledEffect<Drift, DriftParameters> {
 public:
  using P = DriftParameters;
  static constexpr std::string_view kName = "drift";
  static constexpr std::array<ParameterSpec<P>, 4> kSpecs{{
      {"offset_m", &P::offset_m, {-1.0, 1.0}},
      {"warmup_offset_m", &P::warmup_offset_m, {-1.0, 1.0}},
      {"warmup_time_s", &P::warmup_time_s, {0.01, 1e6}},
      {"rate_m_per_h", &P::rate_m_per_h, {-1.0, 1.0}},
  }};
  using TabledEffect::TabledEffect;

  // Common mode: one offset per column, whatever the beam.
  double offset_at(double time_s) const {
    const P& p = params();
    return p.offset_m + p.warmup_offset_m * std::exp(-time_s / p.warmup_time_s) + p.rate_m_per_h * time_s / 3600.0;
  }

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    const double offset = offset_at(context.time_s);
    float* range = measured.range_m.data();
    for (size_t beam = 0; beam < ideal.size(); ++beam) {
      if (range[beam] != 0.0f) range[beam] = static_cast<float>(static_cast<double>(range[beam]) + offset);
    }
  }

  void predict(const IdealReturn&, const ColumnContext& context, Prediction& prediction) const override {
    prediction.bias_m += offset_at(context.time_s);
  }
};

}  // namespace

std::unique_ptr<Effect> make_drift(const nlohmann::json& params, const Location& at) {
  return Drift::create(params, at);
}

EffectCard drift_card() {
  return {.catalogue = "E12",
          .candidate = true,
          .fit = {{"offset_m", 0.0, 0.005}, {"warmup_offset_m", 0.0, 0.01}, {"warmup_time_s", 1.0, 0.5}}};
}

}  // namespace lidartwin::effects_detail
