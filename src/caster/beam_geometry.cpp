// Beam rays as the exact inverse of the SDK's XYZ projection (protocol doc 7.1, 7.2).
#include "lidartwin/caster/beam_geometry.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

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

RayPacket16 make_packet(const BeamRay* column, int first_row, int rows) {
  RayPacket16 packet;
  packet.first_row = first_row;
  packet.count = std::min(RayPacket16::kLanes, rows - first_row);
  for (int i = 0; i < RayPacket16::kLanes; ++i) {
    const BeamRay& ray = column[first_row + std::min(i, packet.count - 1)];
    packet.org_x[i] = ray.origin_m.x();
    packet.org_y[i] = ray.origin_m.y();
    packet.org_z[i] = ray.origin_m.z();
    packet.dir_x[i] = ray.direction.x();
    packet.dir_y[i] = ray.direction.y();
    packet.dir_z[i] = ray.direction.z();
    packet.tnear[i] = ray.range_offset_m;
  }
  return packet;
}

}  // namespace

SdkLutEntry sdk_lut_entry(const BeamIntrinsics& beams, int columns_per_frame, int row, int measurement_id) {
  constexpr double pi = std::numbers::pi;
  const size_t r = static_cast<size_t>(row);
  // 7.1: encoder angle falls as the measurement id grows; note the minus on the beam azimuth.
  const double theta_e = 2.0 * pi - measurement_id * 2.0 * pi / columns_per_frame;
  const double theta_a = -beams.azimuth_deg[r] * pi / 180.0;
  const double phi = beams.altitude_deg[r] * pi / 180.0;
  const double b03 = beams.beam_to_lidar[3];
  const double b23 = beams.beam_to_lidar[11];
  const double n = b23 == 0.0 ? b03 : std::sqrt(b03 * b03 + b23 * b23);
  const Eigen::Vector3d d(std::cos(theta_e + theta_a) * std::cos(phi), std::sin(theta_e + theta_a) * std::cos(phi),
                          std::sin(phi));
  const Eigen::Vector3d o(b03 * std::cos(theta_e) - n * d.x(), b03 * std::sin(theta_e) - n * d.y(), b23 - n * d.z());
  // Apply lidar_to_sensor (translation in mm), then scale mm -> m.
  const Eigen::Matrix3d rotation = rotation_of(beams.lidar_to_sensor);
  return {rotation * d, kRangeUnit * (rotation * o + translation_of(beams.lidar_to_sensor))};
}

BeamGeometry::BeamGeometry(const BeamIntrinsics& beams, int columns_per_frame)
    : columns_(columns_per_frame), rows_(beams.pixels_per_column()), beams_(beams) {
  assert(beams.azimuth_deg.size() == beams.altitude_deg.size());
  const double b03 = beams.beam_to_lidar[3];
  const double b23 = beams.beam_to_lidar[11];
  const double n_mm = b23 == 0.0 ? b03 : std::sqrt(b03 * b03 + b23 * b23);
  rays_.resize(static_cast<size_t>(columns_) * static_cast<size_t>(rows_));
  for (int m = 0; m < columns_; ++m) {
    for (int row = 0; row < rows_; ++row) {
      const SdkLutEntry entry = sdk_lut_entry(beams, columns_, row, m);
      BeamRay& ray = rays_[static_cast<size_t>(m * rows_ + row)];
      ray.origin_m = entry.origin_m.cast<float>();
      ray.direction = entry.direction.cast<float>();
      ray.range_offset_m = static_cast<float>(kRangeUnit * n_mm);
    }
  }
  packets_per_column_ = (rows_ + RayPacket16::kLanes - 1) / RayPacket16::kLanes;
  packets_.reserve(static_cast<size_t>(columns_ * packets_per_column_));
  for (int m = 0; m < columns_; ++m) {
    for (int first = 0; first < rows_; first += RayPacket16::kLanes)
      packets_.push_back(make_packet(&ray(0, m), first, rows_));
  }
}

Eigen::Vector3d BeamGeometry::point(int row, int measurement_id, double range_mm) const {
  if (range_mm == 0.0) return Eigen::Vector3d::Zero();  // 7.1: range 0 gives (0, 0, 0)
  const SdkLutEntry entry = sdk_lut_entry(beams_, columns_, row, measurement_id);
  return range_mm * kRangeUnit * entry.direction + entry.origin_m;
}

}  // namespace lidartwin
