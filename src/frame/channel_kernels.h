#pragma once
// The channel encoder's conversions of one column (channel_encoder.cpp), as a SIMD kernel chosen at
// run time for the CPU (Google Highway). Multiply, compare, add 0.5, truncate to int32, multiply by
// the step: the same IEEE operations on every target, so every target writes the same values.
#include <cstddef>
#include <cstdint>

namespace lidartwin::frame_detail {

// One channel of a column: values (physical units) to protocol units in out. A range channel
// gives int(v * scale + 0.5) * step where low <= v * scale < high, else 0 (and for NaN); any
// other gives int(clamp(v * scale, 0, high) + 0.5) * step, negative or NaN giving 0.
struct ChannelConversion {
  const float* values;
  uint32_t* out;
  bool range;
  float scale;
  float low;  // range channels only
  float high;
  int32_t step;
};
// Every channel of a column at once (one dispatch a column), rows values each.
void convert_channels(const ChannelConversion* channels, size_t count, size_t rows);

}  // namespace lidartwin::frame_detail
