#pragma once
// IMU UDP packets (protocol doc 5).
#include <array>
#include <cstdint>
#include <optional>
#include <span>

namespace lidartwin {

inline constexpr size_t kLegacyImuPacketSize = 48;

// LEGACY IMU (5.1): acceleration in g, angular velocity in deg/s, IMU frame.
struct ImuSample {
  uint64_t sys_ts_ns = 0;
  uint64_t accel_ts_ns = 0;
  uint64_t gyro_ts_ns = 0;
  std::array<float, 3> accel_g{};
  std::array<float, 3> gyro_deg_s{};
  friend bool operator==(const ImuSample&, const ImuSample&) = default;
};

void encode_legacy_imu(const ImuSample& sample, std::span<uint8_t, kLegacyImuPacketSize> out);
std::optional<ImuSample> decode_legacy_imu(std::span<const uint8_t> packet);

}  // namespace lidartwin
