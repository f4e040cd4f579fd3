#pragma once
// One frame (or part of one) of lidar data in protocol units: what packets carry, decoded.
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "lidartwin/packet/data_format.h"

namespace lidartwin {

// Per-packet header fields (protocol doc 4.3). LEGACY packets carry only frame_id (per column).
struct PacketHeader {
  uint16_t packet_type = 1;  // 1 lidar, 2 IMU, 3 zone
  uint32_t frame_id = 0;     // u16 (STANDARD, LEGACY) or u32 (FUSA)
  uint32_t init_id = 0;      // 24 bits
  uint64_t prod_sn = 0;      // 40 bits
  uint8_t alert_flags = 0;
  uint8_t countdown_thermal_shutdown = 0;
  uint8_t countdown_shot_limiting = 0;
  uint8_t thermal_shutdown = 0;
  uint8_t shot_limiting = 0;
  friend bool operator==(const PacketHeader&, const PacketHeader&) = default;
};

// Channels are stored column-major: pixel (column c, row r) is element c*height + r, so one
// column's pixels are contiguous (the caster writes a column, the encoder reads a packet's columns).
// Only the channels the profile carries are allocated; the others are empty.
struct Scan {
  Scan() = default;
  explicit Scan(const LidarDataFormat& format);  // sized W x H, channels of format's profile, all zero

  int width = 0;
  int height = 0;
  PacketHeader header;                    // of the frame (from its first packet when decoded)
  std::vector<uint64_t> timestamp_ns;     // [W], column timestamps
  std::vector<uint32_t> status;           // [W], bit 0 = valid; LEGACY valid = 0xFFFFFFFF
  std::vector<uint64_t> packet_received;  // [W / columns_per_packet], non-zero once a packet arrived
  std::array<std::vector<uint32_t>, kChannelFieldCount> channels;

  bool has(ChannelField f) const { return !channels[static_cast<int>(f)].empty(); }
  // Whether column c was measured: bit 0 of its status, which is how the SDK reads it in every
  // profile (4.2, 4.4). (Whether its packet arrived at all is packet_received's.)
  bool column_valid(int c) const { return (status[static_cast<size_t>(c)] & 1u) != 0; }
  std::span<uint32_t> column(ChannelField f, int c) {
    return {channels[static_cast<int>(f)].data() + static_cast<size_t>(c) * static_cast<size_t>(height),
            static_cast<size_t>(height)};
  }
  std::span<const uint32_t> column(ChannelField f, int c) const {
    return {channels[static_cast<int>(f)].data() + static_cast<size_t>(c) * static_cast<size_t>(height),
            static_cast<size_t>(height)};
  }
  uint32_t& at(ChannelField f, int c, int r) {
    return channels[static_cast<int>(f)][static_cast<size_t>(c * height + r)];
  }
  uint32_t at(ChannelField f, int c, int r) const {
    return channels[static_cast<int>(f)][static_cast<size_t>(c * height + r)];
  }
};

// The status a measured column carries (4.2, 4.4): LEGACY all ones, the other profiles bit 0.
constexpr uint32_t valid_column_status(UdpProfileLidar profile) {
  return profile == UdpProfileLidar::kLegacy ? 0xFFFF'FFFFu : 1u;
}

}  // namespace lidartwin
