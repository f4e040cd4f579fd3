#pragma once
// The channel encoder's conversions of one column (channel_encoder.cpp), as SIMD kernels chosen at
// run time for the CPU (Google Highway). Multiply, compare, add 0.5, truncate to int32, multiply by
// the step: the same IEEE operations on every target, so every target writes the same values.
#include <cstddef>
#include <cstdint>

namespace lidartwin::frame_detail {

// out[r] = int(v * to_steps + 0.5) * step where lowest <= v * to_steps < highest, else 0 (and for NaN).
void range_steps(const float* values, size_t rows, float to_steps, float lowest, float highest, int32_t step,
                 uint32_t* out);
// out[r] = int(clamp(v * inverse_step, 0, highest) + 0.5) * step; negative or NaN gives 0.
void clamped_steps(const float* values, size_t rows, float inverse_step, float highest, int32_t step, uint32_t* out);

}  // namespace lidartwin::frame_detail
