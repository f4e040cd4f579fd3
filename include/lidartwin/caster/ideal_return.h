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
  bool hit() const { return range_m > 0.0f; }
};

}  // namespace lidartwin
