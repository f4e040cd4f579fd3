#pragma once
// The ray of every (beam, measurement id) in the sensor frame: the exact inverse of the SDK's XYZ
// projection (protocol doc 7.1/7.2), so the SDK rebuilds exactly the points we hit.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "lidartwin/profile/beam_intrinsics.h"

namespace lidartwin {

// Casting from origin_m along direction with tnear = range_offset_m starts the physical ray at the
// beam origin; the distance from origin_m to a hit is exactly the range the SDK expects (7.2).
struct BeamRay {
  Eigen::Vector3f origin_m;   // the SDK's virtual origin, n mm behind the beam origin (sensor frame)
  Eigen::Vector3f direction;  // unit vector (sensor frame)
  float range_offset_m = 0;   // n: ranges shorter than this would start behind the beam origin
};

// One entry of the SDK's XYZ look-up table (7.1) in double precision, sensor frame:
// point = range_mm * 0.001 * direction + origin_m.
struct SdkLutEntry {
  Eigen::Vector3d direction;
  Eigen::Vector3d origin_m;
};
SdkLutEntry sdk_lut_entry(const BeamIntrinsics& beams, int columns_per_frame, int row, int measurement_id);

// The same rays, one row of 16 neighbouring columns at a time (a strip) in Embree's
// structure-of-arrays order: the caster casts a strip as one 16-ray packet (ColumnCaster), whose
// rays lie within 16 column steps (2.8 degrees at 2048 columns) along one row. Embree traverses
// these about twice as fast as a column's 16 consecutive rows, whose four azimuth offsets spread a
// packet over 8.4 x 5.3 degrees (tests/bench/pipeline_bench.cpp). The strips of a column group
// come in cast order (cast_row): rows sharing an azimuth offset, by elevation, so consecutive
// packets stay close too. Rays only: tnear (the range offset) is the same for every ray.
struct RayStrip {
  static constexpr int kColumns = 16;
  alignas(64) float org_x[kColumns];
  alignas(64) float org_y[kColumns];
  alignas(64) float org_z[kColumns];
  alignas(64) float dir_x[kColumns];
  alignas(64) float dir_y[kColumns];
  alignas(64) float dir_z[kColumns];
};

class BeamGeometry {
 public:
  BeamGeometry(const BeamIntrinsics& beams, int columns_per_frame);
  int columns() const { return columns_; }
  int rows() const { return rows_; }
  BeamRay ray(int row, int measurement_id) const;  // from its packet
  // The point the SDK computes for a range in mm (7.1), in the sensor frame, metres.
  Eigen::Vector3d point(int row, int measurement_id, double range_mm) const;
  // Angles between beam axes (radians), for the footprint of a beam across an edge (E6): row r and
  // row r + 1 of a column, and row r in adjacent columns.
  float row_spacing_rad(int row) const { return row_spacing_[static_cast<size_t>(row)]; }
  float column_spacing_rad(int row) const { return column_spacing_[static_cast<size_t>(row)]; }
  // The rays of columns 16g .. 16g + 15 at the row cast_row(k): strip(g, k).x[c] is column 16g + c
  // (columns past the frame's last repeat it). A group's strips are one sequential stream.
  const RayStrip& strip(int group, int k) const {
    return strips_[static_cast<size_t>(group) * static_cast<size_t>(rows_) + static_cast<size_t>(k)];
  }
  int cast_row(int k) const { return cast_order_[static_cast<size_t>(k)]; }  // k-th row in cast order
  float range_offset_m() const { return range_offset_m_; }                   // every ray's tnear

 private:
  int columns_ = 0;
  int rows_ = 0;
  std::vector<RayStrip> strips_;  // [group][k]: the rays
  std::vector<int> cast_order_;   // [k]: a row
  std::vector<int> cast_index_;   // [row]: its k
  float range_offset_m_ = 0.0f;
  BeamIntrinsics beams_;               // for point(), in double precision
  std::vector<float> row_spacing_;     // [rows - 1]
  std::vector<float> column_spacing_;  // [rows]
};

}  // namespace lidartwin
