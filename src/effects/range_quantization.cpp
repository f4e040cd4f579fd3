// E9: ranges are integers on the wire: 1 mm (RNG19, LEGACY) or 8 mm (RNG15 low-data-rate
// profiles, a 15-bit value upshifted by 3). r_hat = step * round(r / step), applied after all
// noise, adds step^2/12 of variance (0.08 mm^2 at 1 mm, 5.3 mm^2 at 8 mm).
#include <cmath>
#include <cstdint>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

// std::nearbyint is a library call on baseline x86-64 (no SSE4.1 roundsd); the conversion is not.
// |x| stays far below 2^62 (ranges under 10 km, steps over 1 nm).
double round_half_away(double x) { return static_cast<double>(static_cast<int64_t>(x >= 0.0 ? x + 0.5 : x - 0.5)); }

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

  void simulate(std::span<const IdealReturn>, const ColumnContext& context,
                std::span<Measurement> measured) const override {
    const double delta = step(context);
    if (delta <= 0.0) return;
    const double inverse = 1.0 / delta;
    for (Measurement& m : measured) {
      if (m.range_m == 0.0f) continue;
      m.range_m = static_cast<float>(delta * round_half_away(static_cast<double>(m.range_m) * inverse));
    }
  }

  void predict(const IdealReturn&, const ColumnContext& context, Prediction& prediction) const override {
    const double delta = step(context);
    prediction.variance_m2 += delta * delta / 12.0;
    prediction.quantization_step_m = delta;
  }
};

}  // namespace

std::unique_ptr<Effect> make_range_quantization(const nlohmann::json& params, std::string_view source) {
  return RangeQuantization::create(params, source);
}

}  // namespace lidartwin::effects_detail
