// The Highway kernel of quantization_kernels.h, compiled once per SIMD target (hwy/foreach_target.h
// includes this file again for each, which is why it stays out of the module's unity build);
// HWY_DYNAMIC_DISPATCH calls the best one the CPU runs. The clamp is std::clamp's comparisons.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "effects/quantization_kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <hwy/highway.h>

#include "effects/quantization_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace lidartwin::effects_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// The largest float below 2^31: the truncation's saturation point.
constexpr float kIntLimit = 2147483520.0f;

void QuantizeRanges(float* range, size_t rows, float inverse_step, double step) {
  const hn::ScalableTag<double> dd;  // doubles for the product; as many floats beside them
  const hn::Rebind<float, decltype(dd)> df;
  const hn::Rebind<int32_t, decltype(dd)> di;
  const size_t lanes = hn::Lanes(dd);
  const auto inverse = hn::Set(df, inverse_step), half = hn::Set(df, 0.5f);
  const auto low = hn::Set(df, -kIntLimit), high = hn::Set(df, kIntLimit);
  const auto step_v = hn::Set(dd, step);
  size_t r = 0;
  for (; r + lanes <= rows; r += lanes) {
    const auto x = hn::Mul(hn::LoadU(df, range + r), inverse);
    auto shifted = hn::Add(x, hn::CopySign(half, x));
    shifted = hn::IfThenElse(hn::Lt(shifted, low), low, hn::IfThenElse(hn::Lt(high, shifted), high, shifted));
    const auto lattice = hn::ConvertTo(df, hn::ConvertTo(di, shifted));
    hn::StoreU(hn::DemoteTo(df, hn::Mul(step_v, hn::PromoteTo(dd, lattice))), df, range + r);
  }
  for (; r < rows; ++r) {
    const float x = range[r] * inverse_step;
    const float shifted = std::clamp(x + std::copysign(0.5f, x), -kIntLimit, kIntLimit);
    range[r] = static_cast<float>(step * static_cast<double>(static_cast<float>(static_cast<int32_t>(shifted))));
  }
}

}  // namespace lidartwin::effects_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lidartwin::effects_detail {

HWY_EXPORT(QuantizeRanges);

void quantize_ranges(float* range, size_t rows, float inverse_step, double step) {
  HWY_DYNAMIC_DISPATCH(QuantizeRanges)(range, rows, inverse_step, step);
}

}  // namespace lidartwin::effects_detail
#endif  // HWY_ONCE
