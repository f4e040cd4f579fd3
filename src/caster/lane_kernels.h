#pragma once
// The caster's arithmetic on a packet's 16 lanes (column_caster.cpp), as SIMD kernels chosen at
// run time for the CPU (Google Highway). Each does the scalar code's IEEE operations in its order
// (a multiply and an add never fused, exact square root and division), so every target gives the
// same rays and returns as any other.
#include <cstddef>
#include <cstdint>

namespace lidartwin::caster_detail {

inline constexpr size_t kLanes = 16;  // RayStrip::kColumns, one Embree packet

// A packet's 16 rays as six 16-lane arrays (structure of arrays, as Embree's RTCRay16).
struct LaneRays {
  const float* org[3];
  const float* dir[3];
};
struct LaneRaysOut {
  float* org[3];
  float* dir[3];
};
// Sensor rays into the world, each lane by its own rotation (row-major, rotation[j][lane]) and
// translation: org' = R org + t, dir' = R dir + 0, each row ((a*x + b*y) + c*z) + d. (The 0 is
// added as before: it turns a -0 direction component into +0, which Embree's reciprocal sees.)
void transform_lanes(const LaneRays& in, const float (*rotation)[kLanes], const float (*translation)[kLanes],
                     const LaneRaysOut& out);
// |n . dir| / |n| for 16 lanes, and 1 where that is not below 1 (rounding, or NaN from a
// degenerate normal).
void cos_incidence_lanes(const float* nx, const float* ny, const float* nz, const float* dx, const float* dy,
                         const float* dz, float* out);
// step[r] = 1 where ranges r and r + 1 differ in hit (range > 0) or miss, or are both hits a depth
// step apart (|a - b| > max(0.3 m, 5 % of the farther)), else 0; r in [0, rows - 1).
void depth_steps(const float* range, size_t rows, uint8_t* step);

// E6's edge partners of one column, every row at once (choose_edge_partner's rule and order).
// Arrays by row, kPartnerRows long (rows beyond the column's hold zeros): the column's range and
// |cos| incidence, and four candidates in choose_edge_partner's order (the rows above and below,
// the columns left and right): range (0: none or a miss), rho * cos(theta), angle to the pixel.
inline constexpr size_t kPartnerRows = 128;  // a multiple of every target's lanes
struct PartnerCandidates {
  const float* range[4];
  const float* reflectance[4];
  const float* spacing[4];
};
struct PartnerChoice {
  float* range;  // 0: no partner
  float* reflectance;
  float* spacing;
};
void edge_partners(const float* range, const float* cos_incidence, const PartnerCandidates& candidates,
                   const PartnerChoice& out);

}  // namespace lidartwin::caster_detail
