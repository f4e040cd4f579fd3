#pragma once
// IMU UDP packets (protocol doc 5).
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "lidartwin/packet/lidar_packet.h"

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

// ACCEL32_GYRO32_NMEA (5.2, FW 3.2+): the lidar packet header with packet_type 2, an NMEA block,
// imu_measurements_per_packet measurements in SI units, and the lidar footer (CRC-64).
struct ImuMeasurement {
  uint64_t timestamp_ns = 0;
  uint16_t measurement_id = 0;  // the lidar column at sample time
  uint16_t status = 0;          // bit 0 = valid
  std::array<float, 3> accel_m_s2{};
  std::array<float, 3> gyro_rad_s{};
  friend bool operator==(const ImuMeasurement&, const ImuMeasurement&) = default;
};

inline constexpr size_t kNmeaSentenceBytes = 85;
// The most measurements that keep a packet within one 65535-byte datagram.
inline constexpr int kMaxImuMeasurementsPerPacket = 1816;

struct NmeaImuPacket {
  PacketHeader header{.packet_type = 2};
  uint64_t nmea_timestamp_ns = 0;
  std::string nmea_sentence;  // at most kNmeaSentenceBytes; zero-padded on the wire
  std::vector<ImuMeasurement> measurements;
  friend bool operator==(const NmeaImuPacket&, const NmeaImuPacket&) = default;
};

size_t nmea_imu_packet_size(int measurements_per_packet);

// out has nmea_imu_packet_size(packet.measurements.size()) bytes. Header fields are truncated to
// their widths as in PacketFormat::encode; a longer sentence is a caller bug (asserted).
void encode_nmea_imu(const NmeaImuPacket& packet, HeaderType header_type, std::span<uint8_t> out,
                     FooterKind footer = FooterKind::kCrc64);

struct DecodedNmeaImu {
  NmeaImuPacket packet;
  FooterKind footer = FooterKind::kCrc64;
  bool crc_ok = true;  // false only when footer == kOther
};
// nullopt, with *error naming the problem, unless bytes is an IMU packet (packet_type 2) of
// exactly nmea_imu_packet_size(measurements_per_packet) bytes.
std::optional<DecodedNmeaImu> decode_nmea_imu(std::span<const uint8_t> bytes, int measurements_per_packet,
                                              HeaderType header_type, std::string* error);

}  // namespace lidartwin
