#pragma once
// Shared by packet_test, fuzz_test and conformance_test: the per-profile field table typed in again
// from protocol doc 4.2/4.6 (independent of src/packet/field_table.cpp), and random scan filling.
#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"

namespace lidartwin::test {

inline constexpr std::array<UdpProfileLidar, 6> kProfiles{
    UdpProfileLidar::kLegacy,           UdpProfileLidar::kRng19Rfl8Sig16Nir16,
    UdpProfileLidar::kRng15Rfl8Nir8,    UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual,
    UdpProfileLidar::kRng15Rfl8Nir8Dual, UdpProfileLidar::kFusaRng15Rfl8Nir8Dual,
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

}  // namespace lidartwin::test
