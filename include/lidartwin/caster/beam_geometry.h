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

// The same rays, four rows of a column at a time in Embree's structure-of-arrays order: the
// caster fills a 16-ray packet with four quads, the same quad of four neighbouring columns, whose
// rays lie close together (ColumnCaster). A column's rows go into quads in cast order: rows that
// share an azimuth offset, by elevation (an OS1-128's four offsets 2.8 degrees apart, each with
// 32 rows), so a quad spans about 1.3 degrees and a packet of four columns about 1.4 x 4 degrees,
// where 16 consecutive rows span 5.3 x 8.4. Lanes past the last row repeat it (masked off).
// Which rows a quad holds is the same in every column (QuadRows), and so is tnear (the range
// offset): the quads hold only what differs, 96 bytes.
struct RayQuad {
  static constexpr int kLanes = 4;
  alignas(16) float org_x[kLanes];
  alignas(16) float org_y[kLanes];
  alignas(16) float org_z[kLanes];
  alignas(16) float dir_x[kLanes];
  alignas(16) float dir_y[kLanes];
  alignas(16) float dir_z[kLanes];
};
struct QuadRows {
  uint16_t rows[RayQuad::kLanes];  // the row of each lane
  int count = 0;                   // lanes in use
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
  // A column's rays as quads_per_column() quads, in cast order. Stored four columns at a time,
  // quad by quad (the same quad of columns 4g .. 4g + 3 side by side): the caster's packets read
  // one 512-byte run each, and a group of columns one sequential stream.
  static constexpr int kGroupColumns = 4;
  int quads_per_column() const { return quads_per_column_; }
  const QuadRows& quad_rows(int index) const { return quad_rows_[static_cast<size_t>(index)]; }
  float range_offset_m() const { return range_offset_m_; }  // every ray's tnear
  const RayQuad& quad(int measurement_id, int index) const { return quads_[quad_index(measurement_id, index)]; }

 private:
  size_t quad_index(int measurement_id, int index) const {
    const int group = measurement_id / kGroupColumns, column = measurement_id % kGroupColumns;
    return static_cast<size_t>((group * quads_per_column_ + index) * kGroupColumns + column);
  }

  int columns_ = 0;
  int rows_ = 0;
  int quads_per_column_ = 0;
  std::vector<RayQuad> quads_;       // the rays, four columns at a time
  std::vector<QuadRows> quad_rows_;  // [quad]
  std::vector<int> slot_of_row_;     // [row]: quad * 4 + lane
  float range_offset_m_ = 0.0f;
  BeamIntrinsics beams_;               // for point(), in double precision
  std::vector<float> row_spacing_;     // [rows - 1]
  std::vector<float> column_spacing_;  // [rows]
};

}  // namespace lidartwin
