// E5: a pixel is reported only if its photon histogram peak clears a detection threshold; weak
// returns (dark, far, grazing) go missing. Detection is logistic in ln S:
//   P_det = 1 / (1 + exp(-(ln S - ln S_th) / w)),   S_th = threshold + c * sqrt(B)
// with S the expected signal from radiometry (which must come earlier in the chain) and B the
// ambient (NEAR_IR): a fixed false-alarm rate puts the threshold a fixed number of background
// standard deviations up (E14). Default S_th = 4 photons, w = 0.3: with the default radiometry,
// the Gen1 OS1 range spec (40 m at 10 %, 120 m at 80 %, [S1]: S = 8.6 and 7.7 photons) then sits
// at P_det = 0.93 and 0.90.
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

#include "effects/builtin_effects.h"
#include "effects/echo_quadrature.h"
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

  explicit Dropout(const P& p) : TabledEffect(p) {
    for (size_t k = 0; k <= kCells; ++k) {
      const double edge = static_cast<double>(k) / kCells;
      drop_below_[k] = signal_ratio_at(edge - kMargin, p.width);
      detect_from_[k] = signal_ratio_at(edge + kMargin, p.width);
    }
  }

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }
  bool adds_returns() const override { return false; }

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
    for (const uint32_t beam : measured.listed_returns()) {
      if (measured.range_m[beam] == 0.0f) continue;
      const float signal = measured.signal_photons[beam], near_ir = measured.near_ir_photons[beam];
      const double u = streams(beam).uniform(0);
      // u lies in cell k = [k, k + 1) / kCells. Where P_det is above the cell (by the margin) the
      // return is detected, where it is below, dropped, without the log and exp of P_det; only
      // returns whose P_det falls in u's own cell (1 in kCells) compute it. The same outcomes as
      // comparing u with P_det itself.
      // The outcome is a mask, not a branch: for returns with P_det between 0 and 1 it is random,
      // and branches on it mispredicted (from the drone's pose, where far returns are weak, the
      // effect cost 13 ns a return). Float comparisons compiled to jumps whatever the source
      // said, so they are made on the bit patterns (integer arithmetic).
      const auto cell = static_cast<size_t>(u * kCells);
      const float th = threshold(near_ir);
      const float positive = signal > 0.0f ? signal : 0.0f;  // no signal: dropped, as before
      uint32_t detected = at_least(positive, th * detect_from_[cell + 1]);
      const uint32_t undecided = at_least(positive, th * drop_below_[cell]) & (detected ^ 1u);
      if (undecided != 0) detected = u < static_cast<double>(detection_probability(signal, near_ir)) ? 1u : 0u;
      const uint32_t keep = 0u - detected;  // all ones, or zero (+0.0f)
      const auto masked = [keep](float& value) { value = std::bit_cast<float>(std::bit_cast<uint32_t>(value) & keep); };
      masked(measured.range_m[beam]);
      masked(measured.signal_photons[beam]);
      masked(measured.reflectivity[beam]);
    }
  }

  // Where E6 splits the footprint, each echo is detected by its own signal (echo_quadrature.h).
  void predict(const IdealReturn&, const ColumnContext&, Prediction& prediction) const override {
    if (prediction.echo_count > 0) {
      const auto near_ir = static_cast<float>(prediction.near_ir_photons);
      detect_echoes(prediction, [&](double signal) {
        return static_cast<double>(detection_probability(static_cast<float>(signal), near_ir));
      });
      return;
    }
    prediction.p_detect *= static_cast<double>(detection_probability(static_cast<float>(prediction.signal_photons),
                                                                     static_cast<float>(prediction.near_ir_photons)));
  }

 private:
  // 1 if x >= y, for x, y >= 0 (finite or infinite), whose bit patterns are ordered as they are;
  // the difference of two such patterns lies within int32.
  static uint32_t at_least(float x, float y) {
    return 1u ^ (static_cast<uint32_t>(std::bit_cast<int32_t>(x) - std::bit_cast<int32_t>(y)) >> 31);
  }
  static constexpr size_t kCells = 64;
  static constexpr double kMargin = 1e-5;  // in probability: beyond float rounding of P_det
  // S / S_th where P_det = probability: (P / (1 - P))^w; 0 and infinity at the ends.
  static float signal_ratio_at(double probability, double width) {
    if (probability <= 0.0) return 0.0f;
    if (probability >= 1.0) return std::numeric_limits<float>::infinity();
    return static_cast<float>(std::pow(probability / (1.0 - probability), width));
  }
  // [k]: S / S_th at P_det = k / kCells less (drop_below_) and plus (detect_from_) the margin.
  std::array<float, kCells + 1> drop_below_{}, detect_from_{};
};

}  // namespace

std::unique_ptr<Effect> make_dropout(const nlohmann::json& params, const Location& at) {
  return Dropout::create(params, at);
}

EffectCard dropout_card() {
  return {.catalogue = "E5", .candidate = true, .fit = {{"threshold_photons", 1.0, 1.0}, {"width", 0.3, 0.1}}};
}

}  // namespace lidartwin::effects_detail
