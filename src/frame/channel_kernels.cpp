// Highway kernels of channel_kernels.h, compiled once per SIMD target (hwy/foreach_target.h
// includes this file again for each); HWY_DYNAMIC_DISPATCH calls the best one the CPU runs. The
// scalar tails are the vectors' operations lane by lane. Conversions see only values in
// [0, 2^20] (the selects come first), where truncation is exact on every target.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "frame/channel_kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/highway.h>

#include "frame/channel_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace lidartwin::frame_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void RangeSteps(const float* values, size_t rows, float to_steps, float lowest, float highest, int32_t step,
                uint32_t* out) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const hn::RebindToUnsigned<decltype(df)> du;
  const size_t lanes = hn::Lanes(df);
  const auto scale = hn::Set(df, to_steps), low = hn::Set(df, lowest), high = hn::Set(df, highest);
  const auto half = hn::Set(df, 0.5f);
  const auto step_v = hn::Set(di, step);
  size_t r = 0;
  for (; r + lanes <= rows; r += lanes) {
    const auto steps = hn::Mul(hn::LoadU(df, values + r), scale);
    const auto representable = hn::And(hn::Ge(steps, low), hn::Lt(steps, high));  // false for NaN
    const auto safe = hn::IfThenElseZero(representable, hn::Add(steps, half));
    const auto mm = hn::Mul(hn::ConvertTo(di, safe), step_v);
    hn::StoreU(hn::BitCast(du, hn::IfThenElseZero(hn::RebindMask(di, representable), mm)), du, out + r);
  }
  for (; r < rows; ++r) {
    const float steps = values[r] * to_steps;
    const bool representable = steps >= lowest && steps < highest;
    out[r] = static_cast<uint32_t>(representable ? static_cast<int32_t>(steps + 0.5f) * step : 0);
  }
}

void ClampedSteps(const float* values, size_t rows, float inverse_step, float highest, int32_t step, uint32_t* out) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const hn::RebindToUnsigned<decltype(df)> du;
  const size_t lanes = hn::Lanes(df);
  const auto scale = hn::Set(df, inverse_step), high = hn::Set(df, highest), zero = hn::Zero(df);
  const auto half = hn::Set(df, 0.5f);
  const auto step_v = hn::Set(di, step);
  size_t r = 0;
  for (; r + lanes <= rows; r += lanes) {
    auto steps = hn::Mul(hn::LoadU(df, values + r), scale);
    steps = hn::IfThenElse(hn::Gt(steps, zero), steps, zero);  // NaN: 0
    steps = hn::IfThenElse(hn::Lt(steps, high), steps, high);
    hn::StoreU(hn::BitCast(du, hn::Mul(hn::ConvertTo(di, hn::Add(steps, half)), step_v)), du, out + r);
  }
  for (; r < rows; ++r) {
    float steps = values[r] * inverse_step;
    steps = steps > 0.0f ? steps : 0.0f;
    steps = steps < highest ? steps : highest;
    out[r] = static_cast<uint32_t>(static_cast<int32_t>(steps + 0.5f) * step);
  }
}

void ConvertChannels(const ChannelConversion* channels, size_t count, size_t rows) {
  for (size_t k = 0; k < count; ++k) {
    const ChannelConversion& c = channels[k];
    if (c.range) {
      RangeSteps(c.values, rows, c.scale, c.low, c.high, c.step, c.out);
    } else {
      ClampedSteps(c.values, rows, c.scale, c.high, c.step, c.out);
    }
  }
}

}  // namespace lidartwin::frame_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lidartwin::frame_detail {

HWY_EXPORT(ConvertChannels);

void convert_channels(const ChannelConversion* channels, size_t count, size_t rows) {
  HWY_DYNAMIC_DISPATCH(ConvertChannels)(channels, count, rows);
}

}  // namespace lidartwin::frame_detail
#endif  // HWY_ONCE
