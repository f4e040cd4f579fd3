// ACCEL32_GYRO32_NMEA IMU packets (protocol doc 5.2), from tables like the lidar packets: the
// lidar header tables (field_table.cpp), then the NMEA block and measurement tables below.
// Checked byte for byte on imu_zm_no_lidar.pcap (FW 3.2, 8 measurements, valid CRC).
#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cstring>

#include "lidartwin/packet/imu_packet.h"
#include "packet/field_table.h"
#include "packet/footer.h"
#include "packet/packet_format_impl.h"

namespace lidartwin {
namespace {

using packet_detail::FieldCodec;

constexpr size_t kHeaderBytes = 32;
constexpr size_t kNmeaBlockBytes = 100;  // u64 timestamp, 85-byte sentence, 7 reserved
constexpr size_t kNmeaTimestampOffset = kHeaderBytes;
constexpr size_t kNmeaSentenceOffset = kHeaderBytes + 8;
constexpr size_t kMeasurementsOffset = kHeaderBytes + kNmeaBlockBytes;
constexpr size_t kMeasurementBytes = 36;
constexpr size_t kFooterBytes = 32;

enum class ImuField : uint8_t { kTimestamp, kMeasurementId, kStatus, kAx, kAy, kAz, kGx, kGy, kGz };
struct ImuFieldSpec {
  ImuField field;
  packet_detail::FieldSpec bits;  // within one measurement
};
constexpr std::array<ImuFieldSpec, 9> kMeasurementFields{{
    {ImuField::kTimestamp, {0, 64}},
    {ImuField::kMeasurementId, {64, 16}},
    {ImuField::kStatus, {80, 16}},
    {ImuField::kAx, {96, 32}},
    {ImuField::kAy, {128, 32}},
    {ImuField::kAz, {160, 32}},
    {ImuField::kGx, {192, 32}},
    {ImuField::kGy, {224, 32}},
    {ImuField::kGz, {256, 32}},
}};

// Floats travel as their IEEE-754 bit patterns (little-endian, like every field).
uint64_t measurement_value(const ImuMeasurement& m, ImuField field) {
  switch (field) {
    case ImuField::kTimestamp: return m.timestamp_ns;
    case ImuField::kMeasurementId: return m.measurement_id;
    case ImuField::kStatus: return m.status;
    case ImuField::kAx: return std::bit_cast<uint32_t>(m.accel_m_s2[0]);
    case ImuField::kAy: return std::bit_cast<uint32_t>(m.accel_m_s2[1]);
    case ImuField::kAz: return std::bit_cast<uint32_t>(m.accel_m_s2[2]);
    case ImuField::kGx: return std::bit_cast<uint32_t>(m.gyro_rad_s[0]);
    case ImuField::kGy: return std::bit_cast<uint32_t>(m.gyro_rad_s[1]);
    case ImuField::kGz: return std::bit_cast<uint32_t>(m.gyro_rad_s[2]);
  }
  return 0;
}

void set_measurement_value(ImuMeasurement& m, ImuField field, uint64_t v) {
  const auto f = std::bit_cast<float>(static_cast<uint32_t>(v));
  switch (field) {
    case ImuField::kTimestamp: m.timestamp_ns = v; break;
    case ImuField::kMeasurementId: m.measurement_id = static_cast<uint16_t>(v); break;
    case ImuField::kStatus: m.status = static_cast<uint16_t>(v); break;
    case ImuField::kAx: m.accel_m_s2[0] = f; break;
    case ImuField::kAy: m.accel_m_s2[1] = f; break;
    case ImuField::kAz: m.accel_m_s2[2] = f; break;
    case ImuField::kGx: m.gyro_rad_s[0] = f; break;
    case ImuField::kGy: m.gyro_rad_s[1] = f; break;
    case ImuField::kGz: m.gyro_rad_s[2] = f; break;
  }
}

std::optional<DecodedNmeaImu> failure(std::string* error, std::string message) {
  if (error != nullptr) *error = "IMU packet: " + std::move(message);
  return std::nullopt;
}

}  // namespace

size_t nmea_imu_packet_size(int measurements_per_packet) {
  return kMeasurementsOffset + static_cast<size_t>(std::max(measurements_per_packet, 0)) * kMeasurementBytes +
         kFooterBytes;
}

void encode_nmea_imu(const NmeaImuPacket& packet, HeaderType header_type, std::span<uint8_t> out, FooterKind footer) {
  assert(out.size() == nmea_imu_packet_size(static_cast<int>(packet.measurements.size())));
  assert(packet.nmea_sentence.size() <= kNmeaSentenceBytes);
  std::fill(out.begin(), out.end(), uint8_t{0});
  for (const auto& spec : packet_detail::header_spec(header_type)) {
    const FieldCodec codec = FieldCodec::from(spec.bits);
    codec.set(out, packet_detail::header_value(packet.header, spec.field) & codec.max_value());
  }
  std::memcpy(out.data() + kNmeaTimestampOffset, &packet.nmea_timestamp_ns, sizeof(uint64_t));
  std::copy_n(packet.nmea_sentence.begin(), std::min(packet.nmea_sentence.size(), kNmeaSentenceBytes),
              out.begin() + kNmeaSentenceOffset);
  for (size_t i = 0; i < packet.measurements.size(); ++i) {
    const auto slot = out.subspan(kMeasurementsOffset + i * kMeasurementBytes, kMeasurementBytes);
    for (const auto& [field, bits] : kMeasurementFields) {
      FieldCodec::from(bits).set(slot, measurement_value(packet.measurements[i], field));
    }
  }
  packet_detail::write_footer(out, footer);
}

std::optional<DecodedNmeaImu> decode_nmea_imu(std::span<const uint8_t> bytes, int measurements_per_packet,
                                              HeaderType header_type, std::string* error) {
  if (measurements_per_packet < 1 || measurements_per_packet > kMaxImuMeasurementsPerPacket) {
    return failure(error, "imu_measurements_per_packet must be 1.." + std::to_string(kMaxImuMeasurementsPerPacket) +
                              ", got " + std::to_string(measurements_per_packet));
  }
  const size_t expected = nmea_imu_packet_size(measurements_per_packet);
  if (bytes.size() != expected) {
    return failure(error, std::to_string(bytes.size()) + " bytes, expected " + std::to_string(expected));
  }
  DecodedNmeaImu decoded;
  NmeaImuPacket& p = decoded.packet;
  for (const auto& spec : packet_detail::header_spec(header_type)) {
    packet_detail::set_header_value(p.header, spec.field, FieldCodec::from(spec.bits).get(bytes));
  }
  if (p.header.packet_type != 2) {
    return failure(error, "packet_type " + std::to_string(p.header.packet_type) + ", expected 2 (IMU)");
  }
  std::memcpy(&p.nmea_timestamp_ns, bytes.data() + kNmeaTimestampOffset, sizeof(uint64_t));
  const auto sentence = bytes.subspan(kNmeaSentenceOffset, kNmeaSentenceBytes);
  p.nmea_sentence.assign(sentence.begin(), std::find(sentence.begin(), sentence.end(), uint8_t{0}));
  p.measurements.resize(static_cast<size_t>(measurements_per_packet));
  for (size_t i = 0; i < p.measurements.size(); ++i) {
    const auto slot = bytes.subspan(kMeasurementsOffset + i * kMeasurementBytes, kMeasurementBytes);
    for (const auto& [field, bits] : kMeasurementFields) {
      set_measurement_value(p.measurements[i], field, FieldCodec::from(bits).get(slot));
    }
  }
  std::tie(decoded.footer, decoded.crc_ok) = packet_detail::classify_footer(bytes);
  return decoded;
}

}  // namespace lidartwin
