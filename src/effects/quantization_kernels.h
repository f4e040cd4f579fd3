#pragma once
// range_quantization's loop over a column (E9), as a SIMD kernel chosen at run time for the CPU
// (Google Highway), with the scalar code's IEEE operations on every target: the same ranges.
#include <cstddef>

namespace lidartwin::effects_detail {

// range[r] = float(step * double(round_half_away(range[r] * inverse_step))): the nearest float to
// the lattice point, rounding half away from zero (in float, through int32, saturating at +-2^31).
void quantize_ranges(float* range, size_t rows, float inverse_step, double step);

}  // namespace lidartwin::effects_detail
