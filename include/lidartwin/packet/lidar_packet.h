#pragma once
// Ouster lidar UDP packets, encoded and decoded from data tables (STYLE.md "Packet format as data").
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/scan.h"

namespace lidartwin {

// CRC-64/XZ (protocol doc 4.5), which every packet the daemon sends carries (liblzma's lzma_crc64).
uint64_t crc64_xz(std::span<const uint8_t> bytes);

// How the last 8 bytes of a non-legacy packet were (or are to be) filled (protocol doc 4.5).
// kFw2Marker: 0xDEADBEEF0000C0DE, as FW 2.3/2.4 send. kZero: all zero, as FW 2.2 and the FW 3.1
// FUSA sample send (the SDK sees no CRC in FUSA packets). kOther: neither these nor a valid CRC
// (decode only; encode leaves zeros). kNone: LEGACY packets have no footer.
enum class FooterKind { kCrc64, kFw2Marker, kOther, kZero, kNone };
inline constexpr uint64_t kFw2FooterMarker = 0xDEADBEEF0000C0DEull;

// Built once from a data format, then only read (like the SDK's PacketFormat). Construction
// validates the format (pixels 1-128, columns_per_packet 1-64 dividing the width, size <= 65535)
// and throws InputError naming the bad value.
class PacketFormat {
 public:
  explicit PacketFormat(const LidarDataFormat& format);

  const LidarDataFormat& format() const;
  size_t lidar_packet_size() const;
  size_t imu_packet_size() const;
  size_t column_size() const;
  int packets_per_frame() const;  // packets that carry at least one column of column_window
  // Whether the packet starting at first_column carries a column of column_window (is sent).
  bool packet_in_window(int first_column) const;
  bool has_channel(ChannelField field) const;
  // Pixel channel value limits: largest value representable (after upshift) and the step (1 << upshift).
  uint32_t channel_max(ChannelField field) const;
  uint32_t channel_step(ChannelField field) const;

  // Writes the packet carrying columns [first_column, first_column + columns_per_packet) of scan
  // into out (size lidar_packet_size()); no allocation. Header fields come from header, truncated
  // to their widths (frame_id wraps at 2^16, or 2^32 with the FUSA header); LEGACY encoder counts
  // derive from measurement ids (m * 90112 / W); the CRC is computed when footer == kCrc64.
  // Channel values wider than their field are a caller bug (asserted); RNG15 ranges are in mm and
  // lose their low 3 bits. The FUSA profile always uses the FUSA header (protocol doc 4.3).
  void encode(const PacketHeader& header, const Scan& scan, int first_column, std::span<uint8_t> out,
              FooterKind footer = FooterKind::kCrc64) const;

  // Whether packets end in a CRC-64 footer (every non-legacy profile but FUSA's).
  bool has_crc() const;
  // Rewrites the frame_id of an encoded packet (the header's, or each LEGACY column's) and, where
  // its footer held a valid CRC, the CRC: what a sensor whose frame counter jumped would send.
  void set_frame_id(std::span<uint8_t> packet, uint32_t frame_id) const;

  struct Decoded {
    PacketHeader header;
    int first_measurement_id = 0;
    FooterKind footer = FooterKind::kCrc64;
    bool crc_ok = true;  // false only when footer == kOther (a CRC that does not match)
  };
  // Reads one lidar packet into scan (columns placed by measurement_id; ids >= W are skipped).
  // Pixels of invalid (status bit 0 = 0) columns are decoded too; real FW sends them as zeros.
  // scan.packet_received[m / columns_per_packet] is incremented, and scan.header is set from the
  // first packet the scan receives. Returns nullopt and sets *error (if not null, naming the
  // problem) when the packet or the scan does not fit this format; the scan is then unchanged.
  std::optional<Decoded> decode(std::span<const uint8_t> packet, Scan& scan, std::string* error) const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

}  // namespace lidartwin
