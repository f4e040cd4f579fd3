#pragma once
// The lidar packet formats as data (protocol doc 4): per-pixel channel tables per udp_profile_lidar,
// packet header tables per header type, and the column framing of the LEGACY and non-legacy layouts.
// PacketFormat turns these into FieldCodecs once; no code branches on a profile name.
#include <cstdint>
#include <optional>
#include <span>

#include "lidartwin/packet/data_format.h"
#include "packet/field_codec.h"

namespace lidartwin::packet_detail {

struct ChannelSpec {
  ChannelField field;
  FieldSpec bits;  // within one pixel
};

enum class HeaderField : uint8_t {
  kPacketType,
  kFrameId,
  kInitId,
  kProdSn,
  kAlertFlags,
  kCountdownThermalShutdown,
  kCountdownShotLimiting,
  kThermalShutdown,
  kShotLimiting,
};
struct HeaderSpec {
  HeaderField field;
  FieldSpec bits;  // within the packet header
};

// kEncoderCount is derived from the measurement id when encoding (protocol doc 4.2); kFrameId in
// a column header carries the packet header's frame_id (LEGACY has no packet header).
enum class ColumnField : uint8_t { kTimestamp, kMeasurementId, kFrameId, kEncoderCount, kStatus };
struct ColumnSpec {
  ColumnField field;
  FieldSpec bits;  // within the column header, or within the column footer
};

// Everything around the pixels. The CRC (or FW 2 marker) sits in the last 8 bytes of the packet
// footer when crc_footer is set (protocol doc 4.5).
struct PacketLayout {
  int packet_header_bytes = 0;
  int column_header_bytes = 0;
  std::span<const ColumnSpec> column_header;
  int column_footer_bytes = 0;
  std::span<const ColumnSpec> column_footer;
  int packet_footer_bytes = 0;
  bool crc_footer = false;
};

struct ProfileSpec {
  UdpProfileLidar profile;
  int pixel_bytes = 0;  // channel_data_size (protocol doc 4.1)
  std::span<const ChannelSpec> channels;
  const PacketLayout* layout = nullptr;
  // Set when the profile fixes the header type whatever lidar_data_format.header_type says.
  std::optional<HeaderType> header_type;
};

const ProfileSpec& profile_spec(UdpProfileLidar profile);
// Empty for layouts without a packet header.
std::span<const HeaderSpec> header_spec(HeaderType type);

inline constexpr int kCrcBytes = 8;
// Pixels are assembled in up to three 64-bit words; no channel field crosses a word boundary.
inline constexpr int kMaxPixelBytes = 24;

}  // namespace lidartwin::packet_detail
