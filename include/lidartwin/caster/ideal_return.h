#pragma once
// What a perfect sensor would see along one beam: the input of the effect chain.
#include <cstdint>

namespace lidartwin {

struct IdealReturn {
  float range_m = 0.0f;        // along the beam from the SDK's virtual origin; 0 = no hit
  float cos_incidence = 1.0f;  // |cos| of the angle between beam and surface normal
  float reflectivity = 0.0f;   // diffuse, 0..1 (material)
  float specular = 0.0f;
  uint32_t material_id = 0;  // Embree geomID, for the analysis' per-material tests
  uint8_t retroreflective = 0;
  uint8_t edge = 0;   // 1 when a neighbouring pixel's range differs by a depth step
  uint16_t beam = 0;  // row of the column, for per-beam effects' predict (E10)
  // E6: the neighbouring pixel across a depth step whose surface this beam's footprint may
  // straddle (choose_edge_partner): its range (0 = none), its rho * cos(theta), and the angle
  // between the two beams' axes. Set only where an effect needs it (Effect::needs_edge_partners).
  float partner_range_m = 0.0f;
  float partner_reflectance = 0.0f;
  float partner_spacing_rad = 0.0f;
  // E8: the nearest retroreflective hit in the same column within kRetroReachRows rows (all beams
  // of a column fire at once, so its stray light reaches their detectors): how many rows away
  // (0 = none, or this pixel is one) and its range. Set by the caster for every column.
  float retro_range_m = 0.0f;
  uint8_t retro_rows = 0;
  static constexpr uint8_t kRetroReachRows = 8;
  bool hit() const { return range_m > 0.0f; }
  bool has_partner() const { return partner_range_m > 0.0f; }
};

}  // namespace lidartwin
