// E14 (lidar-physics.md "Sunlight / ambient: false returns"): ambient photons raise the histogram's
// floor, and now and then a noise peak clears the detection threshold. A pixel without a return
// (nothing hit, or dropped by E5 earlier in the chain) becomes a point with probability
//   p_fa = min(1, probability_at_reference * B / reference_near_ir_photons)
// proportional to the ambient B (NEAR_IR, from radiometry: the in-data proxy for sunlight), at a
// range uniform over (0, max_range_m] with a low SIGNAL. The vendor's anchor is a false-positive
// rate of 1/10,000 at 100 klx of sun ([S1], the default probability); which NEAR_IR count 100 klx
// gives is not published, so reference_near_ir_photons (default 1000) is a value to fit or set
// from a sunlit capture. Place it after dropout and before range_limits, which windows the range
// as for any return. REFLECTIVITY of a false alarm is 0: no surface was calibrated.
#include <algorithm>
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct FalseAlarmParameters {
  double probability_at_reference = 1e-4;
  double reference_near_ir_photons = 1000.0;
  double max_range_m = 100.0;
  double signal_photons = 3.0;
};

class FalseAlarms final : public TabledEffect<FalseAlarms, FalseAlarmParameters> {
 public:
  using P = FalseAlarmParameters;
  static constexpr std::string_view kName = "false_alarms";
  static constexpr std::array<ParameterSpec<P>, 4> kSpecs{{
      {"probability_at_reference", &P::probability_at_reference, {0.0, 1.0}},
      {"reference_near_ir_photons", &P::reference_near_ir_photons, {1e-3, 1e6}},
      {"max_range_m", &P::max_range_m, {0.1, 10000.0}},
      {"signal_photons", &P::signal_photons, {0.0, 1e5}},
  }};
  explicit FalseAlarms(const P& p)
      : TabledEffect(p), per_photon_(p.probability_at_reference / p.reference_near_ir_photons) {}

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  // The same arithmetic serves both directions, so they agree to the last bit.
  double probability(double near_ir) const { return std::min(1.0, per_photon_ * near_ir); }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    for (uint32_t beam = 0; beam < measured.size(); ++beam) {
      if (measured.range_m[beam] != 0.0f) continue;
      const double p = probability(static_cast<double>(measured.near_ir_photons[beam]));
      if (p <= 0.0) continue;
      const RandomStream stream = streams(beam);
      if (stream.uniform(0) >= p) continue;
      measured.range_m[beam] = static_cast<float>(params().max_range_m * (1.0 - stream.uniform(1)));  // (0, max]
      measured.signal_photons[beam] = static_cast<float>(params().signal_photons);
      measured.reflectivity[beam] = 0.0f;
    }
  }

  // A missed detection turns into a false alarm with probability p_fa: it joins the detected
  // returns as the broad (uniform) outlier component.
  void predict(const IdealReturn&, const ColumnContext&, Prediction& prediction) const override {
    const double p = probability(prediction.near_ir_photons);
    if (p <= 0.0) return;
    const double detected = prediction.p_detect, alarms = (1.0 - detected) * p;
    prediction.p_detect = detected + alarms;
    if (prediction.p_detect > 0.0) {
      prediction.outlier_mix = (detected * prediction.outlier_mix + alarms) / prediction.p_detect;
    }
  }

 private:
  double per_photon_;  // probability_at_reference / reference_near_ir_photons
};

}  // namespace

std::unique_ptr<Effect> make_false_alarms(const nlohmann::json& params, const Location& at) {
  return FalseAlarms::create(params, at);
}

EffectCard false_alarms_card() { return {.catalogue = "E14"}; }

}  // namespace lidartwin::effects_detail
