// Beam rays as the exact inverse of the SDK's XYZ projection (protocol doc 7.1, 7.2).
#include "lidartwin/caster/beam_geometry.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>  // cross

namespace lidartwin {
namespace {

constexpr double kRangeUnit = 0.001;  // RANGE_UNIT: mm -> m (7.1)

// Top-left 3x3 and last column (mm) of a row-major 4x4.
Eigen::Matrix3d rotation_of(const Mat4& m) {
  Eigen::Matrix3d r;
  r << m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10];
  return r;
}
Eigen::Vector3d translation_of(const Mat4& m) { return {m[3], m[7], m[11]}; }

// The factors of 7.1 that depend on the beam alone, or on the column alone, computed once per row
// and per column: a 2048 x 128 geometry is 262k entries, and the trigonometry of the pixel loop
// then reduces to the two calls that need both angles. Same operations, same bits.
struct RowAngles {
  double theta_a;  // radians, with 7.1's minus
  double cos_phi, sin_phi;
};
struct ColumnAngles {
  double theta_e;
  double cos_e, sin_e;
};
struct LutConstants {
  double b03, b23, n;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation_mm;
};

RowAngles row_angles(const BeamIntrinsics& beams, int row) {
  constexpr double pi = std::numbers::pi;
  const size_t r = static_cast<size_t>(row);
  const double phi = beams.altitude_deg[r] * pi / 180.0;
  return {-beams.azimuth_deg[r] * pi / 180.0, std::cos(phi), std::sin(phi)};
}

ColumnAngles column_angles(int columns_per_frame, int measurement_id) {
  constexpr double pi = std::numbers::pi;
  // 7.1: encoder angle falls as the measurement id grows; note the minus on the beam azimuth.
  const double theta_e = 2.0 * pi - measurement_id * 2.0 * pi / columns_per_frame;
  return {theta_e, std::cos(theta_e), std::sin(theta_e)};
}

LutConstants lut_constants(const BeamIntrinsics& beams) {
  const double b03 = beams.beam_to_lidar[3];
  const double b23 = beams.beam_to_lidar[11];
  const double n = b23 == 0.0 ? b03 : std::sqrt(b03 * b03 + b23 * b23);
  return {b03, b23, n, rotation_of(beams.lidar_to_sensor), translation_of(beams.lidar_to_sensor)};
}

// cos and sin of the pixel's azimuth, theta_e + theta_a (7.1).
struct PixelAzimuth {
  double cos, sin;
};
PixelAzimuth pixel_azimuth(double theta_a, const ColumnAngles& column) {
  const double angle = column.theta_e + theta_a;
  return {std::cos(angle), std::sin(angle)};
}

SdkLutEntry lut_entry(const LutConstants& k, const RowAngles& row, const ColumnAngles& column,
                      const PixelAzimuth& azimuth) {
  const Eigen::Vector3d d(azimuth.cos * row.cos_phi, azimuth.sin * row.cos_phi, row.sin_phi);
  const Eigen::Vector3d o(k.b03 * column.cos_e - k.n * d.x(), k.b03 * column.sin_e - k.n * d.y(), k.b23 - k.n * d.z());
  // Apply lidar_to_sensor (translation in mm), then scale mm -> m.
  return {k.rotation * d, kRangeUnit * (k.rotation * o + k.translation_mm)};
}

// The rows in cast order (RayStrip): sorted by azimuth offset, a gap of more than a quarter degree
// starting a new group, each group in row order (Ouster rows fall in elevation), groups in
// azimuth order. A sensor whose beams share one offset keeps its row order.
std::vector<int> cast_order(const std::vector<RowAngles>& rows) {
  constexpr double kGroupGap = 0.25 * std::numbers::pi / 180.0;
  std::vector<int> by_azimuth(rows.size());
  for (size_t r = 0; r < rows.size(); ++r) by_azimuth[r] = static_cast<int>(r);
  std::stable_sort(by_azimuth.begin(), by_azimuth.end(), [&rows](int a, int b) {
    return rows[static_cast<size_t>(a)].theta_a < rows[static_cast<size_t>(b)].theta_a;
  });
  std::vector<int> order;
  for (size_t begin = 0; begin < by_azimuth.size();) {
    size_t end = begin + 1;
    while (end < by_azimuth.size() && rows[static_cast<size_t>(by_azimuth[end])].theta_a -
                                              rows[static_cast<size_t>(by_azimuth[end - 1])].theta_a <=
                                          kGroupGap) {
      ++end;
    }
    std::vector<int> group(by_azimuth.begin() + static_cast<std::ptrdiff_t>(begin),
                           by_azimuth.begin() + static_cast<std::ptrdiff_t>(end));
    std::sort(group.begin(), group.end());
    order.insert(order.end(), group.begin(), group.end());
    begin = end;
  }
  return order;
}

}  // namespace

SdkLutEntry sdk_lut_entry(const BeamIntrinsics& beams, int columns_per_frame, int row, int measurement_id) {
  const RowAngles row_angle = row_angles(beams, row);
  const ColumnAngles column = column_angles(columns_per_frame, measurement_id);
  return lut_entry(lut_constants(beams), row_angle, column, pixel_azimuth(row_angle.theta_a, column));
}

BeamGeometry::BeamGeometry(const BeamIntrinsics& beams, int columns_per_frame)
    : columns_(columns_per_frame), rows_(beams.pixels_per_column()), beams_(beams) {
  assert(beams.azimuth_deg.size() == beams.altitude_deg.size());
  const LutConstants constants = lut_constants(beams);
  std::vector<RowAngles> rows;
  for (int row = 0; row < rows_; ++row) rows.push_back(row_angles(beams, row));
  // Beams share a few azimuth offsets (an OS1-128 has 16 distinct values among its 128), so a
  // column's pixel azimuths take a cos and sin per distinct offset, not per beam: the same
  // angles, the same bits, an eighth of the trigonometry (it was 5 % of a one-frame `record`).
  std::vector<double> offsets;
  for (const RowAngles& row : rows) offsets.push_back(row.theta_a);
  std::sort(offsets.begin(), offsets.end());
  offsets.erase(std::unique(offsets.begin(), offsets.end()), offsets.end());
  std::vector<size_t> offset_of_row;
  for (const RowAngles& row : rows) {
    offset_of_row.push_back(
        static_cast<size_t>(std::lower_bound(offsets.begin(), offsets.end(), row.theta_a) - offsets.begin()));
  }
  std::vector<PixelAzimuth> azimuths(offsets.size());
  // Written lane by lane straight into the strips, the only copy kept (3 KiB a column). Each
  // float is converted from its own double: Eigen's cast of a whole vector read the entry back
  // with wider loads than the stores that wrote it, a store-forwarding stall per ray.
  cast_order_ = cast_order(rows);
  cast_index_.resize(static_cast<size_t>(rows_));
  for (int k = 0; k < rows_; ++k) cast_index_[static_cast<size_t>(cast_order_[static_cast<size_t>(k)])] = k;
  range_offset_m_ = static_cast<float>(kRangeUnit * constants.n);
  constexpr int kStrip = RayStrip::kColumns;
  const int groups = (columns_ + kStrip - 1) / kStrip;
  strips_.resize(static_cast<size_t>(groups) * static_cast<size_t>(rows_));
  for (int g = 0; g < groups; ++g) {
    for (int c = 0; c < kStrip; ++c) {
      const int m = std::min(g * kStrip + c, columns_ - 1);  // past the frame's end: repeat its last column
      const ColumnAngles column = column_angles(columns_, m);
      for (size_t k = 0; k < offsets.size(); ++k) azimuths[k] = pixel_azimuth(offsets[k], column);
      for (int k = 0; k < rows_; ++k) {
        const auto r = static_cast<size_t>(cast_order_[static_cast<size_t>(k)]);
        const SdkLutEntry entry = lut_entry(constants, rows[r], column, azimuths[offset_of_row[r]]);
        RayStrip& strip = strips_[static_cast<size_t>(g) * static_cast<size_t>(rows_) + static_cast<size_t>(k)];
        strip.org_x[c] = static_cast<float>(entry.origin_m.x());
        strip.org_y[c] = static_cast<float>(entry.origin_m.y());
        strip.org_z[c] = static_cast<float>(entry.origin_m.z());
        strip.dir_x[c] = static_cast<float>(entry.direction.x());
        strip.dir_y[c] = static_cast<float>(entry.direction.y());
        strip.dir_z[c] = static_cast<float>(entry.direction.z());
      }
    }
  }
  const auto angle = [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return static_cast<float>(std::atan2(a.cross(b).norm(), a.dot(b)));  // accurate for small angles
  };
  for (int row = 0; row < rows_; ++row) {
    if (row + 1 < rows_) row_spacing_.push_back(angle(ray(row, 0).direction, ray(row + 1, 0).direction));
    column_spacing_.push_back(columns_ > 1 ? angle(ray(row, 0).direction, ray(row, 1).direction) : 0.0f);
  }
}

BeamRay BeamGeometry::ray(int row, int measurement_id) const {
  const RayStrip& p = strip(measurement_id / RayStrip::kColumns, cast_index_[static_cast<size_t>(row)]);
  const int i = measurement_id % RayStrip::kColumns;
  return {{p.org_x[i], p.org_y[i], p.org_z[i]}, {p.dir_x[i], p.dir_y[i], p.dir_z[i]}, range_offset_m_};
}

Eigen::Vector3d BeamGeometry::point(int row, int measurement_id, double range_mm) const {
  if (range_mm == 0.0) return Eigen::Vector3d::Zero();  // 7.1: range 0 gives (0, 0, 0)
  const SdkLutEntry entry = sdk_lut_entry(beams_, columns_, row, measurement_id);
  return range_mm * kRangeUnit * entry.direction + entry.origin_m;
}

}  // namespace lidartwin
