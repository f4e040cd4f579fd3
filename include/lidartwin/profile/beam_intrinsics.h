#pragma once
// A sensor's beam geometry: the metadata's beam/lidar/imu intrinsics (protocol doc 3.1, 7).
#include <array>
#include <vector>

namespace lidartwin {

using Mat4 = std::array<double, 16>;  // row-major 4x4, translations in mm as in the metadata

inline constexpr Mat4 kIdentity4{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

struct BeamIntrinsics {
  std::vector<double> altitude_deg;  // row 0 = top beam
  std::vector<double> azimuth_deg;
  double lidar_origin_to_beam_origin_mm = 0.0;
  Mat4 beam_to_lidar = kIdentity4;
  Mat4 lidar_to_sensor{-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 36.18, 0, 0, 0, 1};
  Mat4 imu_to_sensor{1, 0, 0, 6.253, 0, 1, 0, -11.775, 0, 0, 1, 7.645, 0, 0, 0, 1};
  int pixels_per_column() const { return static_cast<int>(altitude_deg.size()); }
  friend bool operator==(const BeamIntrinsics&, const BeamIntrinsics&) = default;
};

}  // namespace lidartwin
