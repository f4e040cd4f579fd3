// LEGACY IMU packets (protocol doc 5.1): three u64 timestamps, then six f32, all little-endian.
#include "lidartwin/packet/imu_packet.h"

#include <bit>
#include <cstring>

namespace lidartwin {
namespace {

static_assert(std::endian::native == std::endian::little, "IMU packets are little-endian");

constexpr size_t kAccelOffset = 24;
constexpr size_t kGyroOffset = 36;

template <typename T>
void put(std::span<uint8_t, kLegacyImuPacketSize> out, size_t offset, T value) {
  std::memcpy(out.data() + offset, &value, sizeof value);
}

template <typename T>
T take(std::span<const uint8_t> in, size_t offset) {
  T value;
  std::memcpy(&value, in.data() + offset, sizeof value);
  return value;
}

}  // namespace

void encode_legacy_imu(const ImuSample& sample, std::span<uint8_t, kLegacyImuPacketSize> out) {
  put(out, 0, sample.sys_ts_ns);
  put(out, 8, sample.accel_ts_ns);
  put(out, 16, sample.gyro_ts_ns);
  for (size_t i = 0; i < 3; ++i) {
    put(out, kAccelOffset + 4 * i, sample.accel_g[i]);
    put(out, kGyroOffset + 4 * i, sample.gyro_deg_s[i]);
  }
}

std::optional<ImuSample> decode_legacy_imu(std::span<const uint8_t> packet) {
  if (packet.size() != kLegacyImuPacketSize) return std::nullopt;
  ImuSample sample;
  sample.sys_ts_ns = take<uint64_t>(packet, 0);
  sample.accel_ts_ns = take<uint64_t>(packet, 8);
  sample.gyro_ts_ns = take<uint64_t>(packet, 16);
  for (size_t i = 0; i < 3; ++i) {
    sample.accel_g[i] = take<float>(packet, kAccelOffset + 4 * i);
    sample.gyro_deg_s[i] = take<float>(packet, kGyroOffset + 4 * i);
  }
  return sample;
}

}  // namespace lidartwin
