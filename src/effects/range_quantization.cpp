// E9: ranges are integers on the wire: 1 mm (RNG19, LEGACY) or 8 mm (RNG15 low-data-rate
// profiles, a 15-bit value upshifted by 3). r_hat = step * round(r / step), applied after all
// noise, adds step^2/12 of variance (0.08 mm^2 at 1 mm, 5.3 mm^2 at 8 mm).
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"
#include "effects/quantization_kernels.h"

namespace lidartwin::effects_detail {
namespace {

struct QuantizationParameters {
  double step_m = 0.0;  // 0 = the wire format's step, context.range_step_m
};

class RangeQuantization final : public TabledEffect<RangeQuantization, QuantizationParameters> {
 public:
  using P = QuantizationParameters;
  static constexpr std::string_view kName = "range_quantization";
  static constexpr std::array<ParameterSpec<P>, 1> kSpecs{{
      {"step_m", &P::step_m, {0.0, 1.0}, false},
  }};

  explicit RangeQuantization(const P& p) : TabledEffect(p) {}

  // The context's float step is 0.008f = 0.0080000004 m; rounding it to whole nanometres gives the
  // intended decimal step, so k * step lands on whole millimetres even at 500 m.
  double step(const ColumnContext& context) const {
    if (params().step_m > 0.0) return params().step_m;
    return std::round(static_cast<double>(context.range_step_m) * 1e9) * 1e-9;
  }

  bool adds_returns() const override { return false; }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    const double delta = step(context);
    if (delta <= 0.0) return;
    // The rounding in float, in vectors: r / step is exact to 0.03 steps even at
    // 500 m, so only ranges that close to a half step can round the other way than in exact
    // arithmetic. The product in double, so the result is the float nearest the lattice point.
    // No return (0) rounds to 0: no branch needed. (std::nearbyint would be a library call on
    // baseline x86-64; the kernel rounds half away from zero through an int32 conversion.)
    quantize_ranges(measured.range_m.data(), measured.range_m.size(), static_cast<float>(1.0 / delta), delta);
  }

  void predict(const IdealReturn&, const ColumnContext& context, Prediction& prediction) const override {
    const double delta = step(context);
    prediction.variance_m2 += delta * delta / 12.0;
    prediction.quantization_step_m = delta;
  }
};

}  // namespace

std::unique_ptr<Effect> make_range_quantization(const nlohmann::json& params, const Location& at) {
  return RangeQuantization::create(params, at);
}

EffectCard range_quantization_card() { return {.catalogue = "E9"}; }

}  // namespace lidartwin::effects_detail
