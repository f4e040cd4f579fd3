// E5: a pixel is reported only if its photon histogram peak clears a detection threshold; weak
// returns (dark, far, grazing) go missing. Detection is logistic in ln S:
//   P_det = 1 / (1 + exp(-(ln S - ln S_th) / w)),   S_th = threshold + c * sqrt(B)
// with S the expected signal from radiometry (which must come earlier in the chain) and B the
// ambient (NEAR_IR): a fixed false-alarm rate puts the threshold a fixed number of background
// standard deviations up (E14). Default S_th = 4 photons, w = 0.3: with the default radiometry,
// the Gen1 OS1 range spec (40 m at 10 %, 120 m at 80 %, [S1]: S = 8.6 and 7.7 photons) then sits
// at P_det = 0.93 and 0.90.
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct DropoutParameters {
  double threshold_photons = 4.0;    // S_th where P_det = 1/2 (without ambient)
  double width = 0.3;                // w: logistic width in ln S
  double ambient_coefficient = 0.0;  // c: threshold increase per sqrt(NEAR_IR photon)
};

class Dropout final : public TabledEffect<Dropout, DropoutParameters> {
 public:
  using P = DropoutParameters;
  static constexpr std::string_view kName = "dropout";
  static constexpr std::array<ParameterSpec<P>, 3> kSpecs{{
      {"threshold_photons", &P::threshold_photons, {1e-3, 1e5}},
      {"width", &P::width, {0.01, 10.0}},
      {"ambient_coefficient", &P::ambient_coefficient, {0.0, 100.0}},
  }};

  explicit Dropout(const P& p)
      : TabledEffect(p),
        sure_ratio_(std::exp(kSureX * static_cast<float>(p.width))),
        sure_probability_(static_cast<double>(1.0f / (1.0f + std::exp(-kSureX)))) {}

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }

  // The same float arithmetic serves both directions, so they agree to the last bit.
  float threshold(float near_ir) const {
    const float base = static_cast<float>(params().threshold_photons);
    if (params().ambient_coefficient <= 0.0) return base;
    return base + static_cast<float>(params().ambient_coefficient) * std::sqrt(near_ir);
  }
  float detection_probability(float signal, float near_ir) const {
    if (signal <= 0.0f) return 0.0f;
    const float x = std::log(signal / threshold(near_ir)) / static_cast<float>(params().width);
    return 1.0f / (1.0f + std::exp(-x));
  }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    for (uint32_t beam = 0; beam < measured.size(); ++beam) {
      if (measured.range_m[beam] == 0.0f) continue;
      const float signal = measured.signal_photons[beam], near_ir = measured.near_ir_photons[beam];
      const double u = streams(beam).uniform(0);
      // Strong returns (x >= 6, P_det >= 0.9975) with u below that bound are detected whatever
      // the exact P_det: skips log and exp for most pixels; outcomes change only by float rounding.
      const bool surely = signal >= sure_ratio_ * threshold(near_ir) && u < sure_probability_;
      if (surely || u < static_cast<double>(detection_probability(signal, near_ir))) continue;
      measured.range_m[beam] = 0.0f;
      measured.signal_photons[beam] = 0.0f;
      measured.reflectivity[beam] = 0.0f;
    }
  }

  void predict(const IdealReturn&, const ColumnContext&, Prediction& prediction) const override {
    prediction.p_detect *= static_cast<double>(detection_probability(static_cast<float>(prediction.signal_photons),
                                                                     static_cast<float>(prediction.near_ir_photons)));
  }

 private:
  static constexpr float kSureX = 6.0f;
  float sure_ratio_;         // S / S_th at x = kSureX
  double sure_probability_;  // P_det at x = kSureX
};

}  // namespace

std::unique_ptr<Effect> make_dropout(const nlohmann::json& params, std::string_view source) {
  return Dropout::create(params, source);
}

}  // namespace lidartwin::effects_detail
