#pragma once
// Shared by packet_test, fuzz_test and conformance_test: the per-profile field table typed in again
// from protocol doc 4.2/4.6 (independent of src/packet/field_table.cpp), random scan filling, a
// bitwise CRC and the round-trip check.
#include <algorithm>
#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"

namespace lidartwin::test {

inline constexpr std::array<UdpProfileLidar, 6> kProfiles{
    UdpProfileLidar::kLegacy,
    UdpProfileLidar::kRng19Rfl8Sig16Nir16,
    UdpProfileLidar::kRng15Rfl8Nir8,
    UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual,
    UdpProfileLidar::kRng15Rfl8Nir8Dual,
    UdpProfileLidar::kFusaRng15Rfl8Nir8Dual,
};

struct ExpectedField {
  UdpProfileLidar profile;
  ChannelField field;
  int bit_offset;
  int bit_width;
  int upshift;
};

// Two entries differ from the doc, following the real captures (see field_table.cpp): LEGACY
// REFLECTIVITY is 16 bits (FW 2.0 uses bits 40-47), RNG19 single FLAGS is bits 19-31 (FW 2.3 sets 28).
using P = UdpProfileLidar;
using F = ChannelField;
inline constexpr ExpectedField kExpectedFields[] = {
    {P::kLegacy, F::kRange, 0, 20, 0},
    {P::kLegacy, F::kFlags, 28, 4, 0},
    {P::kLegacy, F::kReflectivity, 32, 16, 0},
    {P::kLegacy, F::kSignal, 48, 16, 0},
    {P::kLegacy, F::kNearIr, 64, 16, 0},
    {P::kRng19Rfl8Sig16Nir16, F::kRange, 0, 19, 0},
    {P::kRng19Rfl8Sig16Nir16, F::kFlags, 19, 13, 0},
    {P::kRng19Rfl8Sig16Nir16, F::kReflectivity, 32, 8, 0},
    {P::kRng19Rfl8Sig16Nir16, F::kSignal, 48, 16, 0},
    {P::kRng19Rfl8Sig16Nir16, F::kNearIr, 64, 16, 0},
    {P::kRng19Rfl8Sig16Nir16, F::kWindow, 88, 8, 0},
    {P::kRng15Rfl8Nir8, F::kRange, 0, 15, 3},
    {P::kRng15Rfl8Nir8, F::kFlags, 15, 1, 0},
    {P::kRng15Rfl8Nir8, F::kReflectivity, 16, 8, 0},
    {P::kRng15Rfl8Nir8, F::kNearIr, 24, 8, 4},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kRange, 0, 19, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kFlags, 19, 5, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kReflectivity, 24, 8, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kRange2, 32, 19, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kFlags2, 51, 5, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kReflectivity2, 56, 8, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kSignal, 64, 16, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kSignal2, 80, 16, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kNearIr, 96, 16, 0},
    {P::kRng19Rfl8Sig16Nir16Dual, F::kWindow, 120, 8, 0},
    {P::kRng15Rfl8Nir8Dual, F::kRange, 0, 15, 3},
    {P::kRng15Rfl8Nir8Dual, F::kFlags, 15, 1, 0},
    {P::kRng15Rfl8Nir8Dual, F::kReflectivity, 16, 8, 0},
    {P::kRng15Rfl8Nir8Dual, F::kNearIr, 24, 8, 4},
    {P::kRng15Rfl8Nir8Dual, F::kRange2, 32, 15, 3},
    {P::kRng15Rfl8Nir8Dual, F::kFlags2, 47, 1, 0},
    {P::kRng15Rfl8Nir8Dual, F::kReflectivity2, 48, 8, 0},
    {P::kRng15Rfl8Nir8Dual, F::kWindow, 56, 8, 0},
    {P::kFusaRng15Rfl8Nir8Dual, F::kRange, 0, 15, 3},
    {P::kFusaRng15Rfl8Nir8Dual, F::kFlags, 15, 1, 0},
    {P::kFusaRng15Rfl8Nir8Dual, F::kReflectivity, 16, 8, 0},
    {P::kFusaRng15Rfl8Nir8Dual, F::kNearIr, 24, 8, 4},
    {P::kFusaRng15Rfl8Nir8Dual, F::kRange2, 32, 15, 3},
    {P::kFusaRng15Rfl8Nir8Dual, F::kFlags2, 47, 1, 0},
    {P::kFusaRng15Rfl8Nir8Dual, F::kReflectivity2, 48, 8, 0},
    {P::kFusaRng15Rfl8Nir8Dual, F::kWindow, 56, 8, 0},
};

inline const ExpectedField* expected_field(UdpProfileLidar profile, ChannelField field) {
  for (const ExpectedField& e : kExpectedFields) {
    if (e.profile == profile && e.field == field) return &e;
  }
  return nullptr;
}

inline bool legacy(UdpProfileLidar p) { return p == UdpProfileLidar::kLegacy; }
inline bool fusa(UdpProfileLidar p) { return p == UdpProfileLidar::kFusaRng15Rfl8Nir8Dual; }

inline LidarDataFormat make_format(UdpProfileLidar profile, int height, int columns_per_packet, int width = 512) {
  LidarDataFormat f;
  f.udp_profile_lidar = profile;
  f.pixels_per_column = height;
  f.columns_per_packet = columns_per_packet;
  f.columns_per_frame = width;
  f.column_window = {0, width - 1};
  return f;
}

// Protocol doc 4.1: framing bytes (packet header, column header, column footer, packet footer)
// and bytes per pixel, typed in independently of the code.
inline size_t doc_packet_size(UdpProfileLidar profile, int height, int columns_per_packet) {
  size_t pixel = 0;
  switch (profile) {
    case P::kLegacy: pixel = 12; break;
    case P::kRng19Rfl8Sig16Nir16: pixel = 12; break;
    case P::kRng15Rfl8Nir8: pixel = 4; break;
    case P::kRng19Rfl8Sig16Nir16Dual: pixel = 16; break;
    case P::kRng15Rfl8Nir8Dual: pixel = 8; break;
    case P::kFusaRng15Rfl8Nir8Dual: pixel = 8; break;
  }
  const auto h = static_cast<size_t>(height);
  const auto cpp = static_cast<size_t>(columns_per_packet);
  return legacy(profile) ? cpp * (16 + h * pixel + 4) : 32 + cpp * (12 + h * pixel) + 32;
}

inline std::vector<uint8_t> from_hex(std::string_view hex) {
  std::vector<uint8_t> bytes;
  for (size_t i = 0; i + 1 < hex.size(); i += 2) {
    bytes.push_back(static_cast<uint8_t>(std::stoi(std::string(hex.substr(i, 2)), nullptr, 16)));
  }
  return bytes;
}

inline uint64_t random_bits(std::mt19937_64& rng, int bits) {
  return bits >= 64 ? rng() : rng() & ((uint64_t{1} << bits) - 1);
}

// Every field of every pixel, every timestamp and status word, masked to its width (doc 4.2/4.4).
inline void fill_random(Scan& scan, UdpProfileLidar profile, std::mt19937_64& rng) {
  for (const ExpectedField& e : kExpectedFields) {
    if (e.profile != profile) continue;
    for (uint32_t& v : scan.channels[static_cast<size_t>(e.field)]) {
      v = static_cast<uint32_t>(random_bits(rng, e.bit_width) << e.upshift);
    }
  }
  for (uint64_t& t : scan.timestamp_ns) t = rng();
  for (uint32_t& s : scan.status) s = static_cast<uint32_t>(random_bits(rng, legacy(profile) ? 32 : 16));
}

// The header fields the profile's packets carry (doc 4.2/4.3), random within their widths.
inline PacketHeader random_header(UdpProfileLidar profile, std::mt19937_64& rng) {
  PacketHeader h;
  h.frame_id = static_cast<uint32_t>(random_bits(rng, fusa(profile) ? 32 : 16));
  if (legacy(profile)) return h;
  h.init_id = static_cast<uint32_t>(random_bits(rng, 24));
  h.prod_sn = random_bits(rng, 40);
  h.alert_flags = static_cast<uint8_t>(random_bits(rng, 8));
  h.countdown_thermal_shutdown = static_cast<uint8_t>(random_bits(rng, 8));
  h.countdown_shot_limiting = static_cast<uint8_t>(random_bits(rng, 8));
  h.thermal_shutdown = static_cast<uint8_t>(random_bits(rng, 4));
  h.shot_limiting = static_cast<uint8_t>(random_bits(rng, 4));
  return h;
}

// CRC-64/XZ one bit at a time, straight from its definition (protocol doc 4.5).
inline uint64_t crc64_bitwise(std::span<const uint8_t> bytes) {
  uint64_t crc = ~uint64_t{0};
  for (uint8_t b : bytes) {
    crc ^= b;
    for (int i = 0; i < 8; ++i) crc = (crc & 1) ? (crc >> 1) ^ 0xC96C5795D7870F42ull : crc >> 1;
  }
  return ~crc;
}

// A zero packet whose first bytes are the given header bytes, decoded.
inline PacketHeader decode_header(UdpProfileLidar profile, const std::string& header_hex) {
  const LidarDataFormat f = make_format(profile, 128, 16, 1024);
  const PacketFormat format(f);
  std::vector<uint8_t> packet(format.lidar_packet_size());
  const auto header = from_hex(header_hex);
  std::copy(header.begin(), header.end(), packet.begin());
  Scan scan(f);
  std::string error;
  const auto decoded = format.decode(packet, scan, &error);
  EXPECT_TRUE(decoded) << error;
  return decoded ? decoded->header : PacketHeader{};
}

inline void expect_scans_equal(const Scan& a, const Scan& b, const std::string& what) {
  for (size_t f = 0; f < a.channels.size(); ++f) {
    EXPECT_EQ(a.channels[f], b.channels[f]) << what << " " << to_string(static_cast<ChannelField>(f));
  }
  EXPECT_EQ(a.timestamp_ns, b.timestamp_ns) << what;
  EXPECT_EQ(a.status, b.status) << what;
}

// Encodes every packet of a random frame, decodes them into a fresh scan, requires equality.
inline void expect_round_trip(const PacketFormat& format, UdpProfileLidar profile, std::mt19937_64& rng) {
  const LidarDataFormat& f = format.format();
  const std::string what = std::string(to_string(profile)) + " H=" + std::to_string(f.pixels_per_column) +
                           " cpp=" + std::to_string(f.columns_per_packet);
  Scan scan(f);
  fill_random(scan, profile, rng);
  Scan decoded(f);
  std::vector<uint8_t> packet(format.lidar_packet_size());
  for (int first = 0; first < f.columns_per_frame; first += f.columns_per_packet) {
    const PacketHeader header = random_header(profile, rng);
    format.encode(header, scan, first, packet);
    std::string error;
    const auto result = format.decode(packet, decoded, &error);
    ASSERT_TRUE(result) << what << ": " << error;
    ASSERT_EQ(result->header, header) << what;
    ASSERT_EQ(result->first_measurement_id, first) << what;
    ASSERT_EQ(result->footer, legacy(profile) ? FooterKind::kNone : FooterKind::kCrc64) << what;
    ASSERT_TRUE(result->crc_ok) << what;
  }
  expect_scans_equal(scan, decoded, what);
  EXPECT_TRUE(std::all_of(decoded.packet_received.begin(), decoded.packet_received.end(), [](uint64_t n) {
    return n == 1;
  })) << what;
}

}  // namespace lidartwin::test
