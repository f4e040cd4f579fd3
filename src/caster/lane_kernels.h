#pragma once
// The caster's arithmetic on a packet's 16 lanes (column_caster.cpp), as SIMD kernels chosen at
// run time for the CPU (Google Highway). Each does the scalar code's IEEE operations in its order
// (a multiply and an add never fused, exact square root and division), so every target gives the
// same rays and returns as any other.
#include <cstddef>
#include <cstdint>

namespace lidartwin::caster_detail {

inline constexpr size_t kLanes = 16;  // RayStrip::kColumns, one Embree packet

// y = ((a*x0 + b*x1) + c*x2) + d over 16 lanes, each with its own a, b, c, d.
void affine_lanes(const float* x0, const float* x1, const float* x2, const float* a, const float* b, const float* c,
                  const float* d, float* y);
// |n . dir| / |n| for 16 lanes, and 1 where that is not below 1 (rounding, or NaN from a
// degenerate normal).
void cos_incidence_lanes(const float* nx, const float* ny, const float* nz, const float* dx, const float* dy,
                         const float* dz, float* out);
// step[r] = 1 where ranges r and r + 1 differ in hit (range > 0) or miss, or are both hits a depth
// step apart (|a - b| > max(0.3 m, 5 % of the farther)), else 0; r in [0, rows - 1).
void depth_steps(const float* range, size_t rows, uint8_t* step);

}  // namespace lidartwin::caster_detail
