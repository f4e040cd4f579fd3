// Scan -> one lidar packet. Runs for every packet the daemon sends: no allocation, one pass.
#include <algorithm>
#include <array>
#include <cassert>
#include <cstring>

#include "packet/footer.h"
#include "packet/packet_format_impl.h"
#include "packet/pixel_kernels.h"

namespace lidartwin {
namespace {

using packet_detail::ColumnField;

uint64_t column_value(const packet_detail::FormatCodecs& impl, ColumnField field, const PacketHeader& header,
                      const Scan& scan, int m) {
  const auto col = static_cast<size_t>(m);
  switch (field) {
    case ColumnField::kTimestamp: return scan.timestamp_ns[col];
    case ColumnField::kMeasurementId: return static_cast<uint64_t>(m);
    case ColumnField::kFrameId: return header.frame_id & 0xFFFF;  // LEGACY: u16 per column (4.2)
    case ColumnField::kEncoderCount:
      return static_cast<uint64_t>(m) * kEncoderTicksPerRevolution /
             static_cast<uint64_t>(impl.format.columns_per_frame);
    case ColumnField::kStatus: return scan.status[col];
  }
  return 0;
}

using ChannelValues = std::array<const uint32_t*, kChannelFieldCount>;

// A channel's place in the pixel as a 32-bit word: every pixel field lies inside one aligned
// 32-bit word (checked at compile time in field_table.cpp), so the 64-bit codec narrows to it.
packet_detail::WordLane word_lane(const packet_detail::FieldCodec& codec) {
  const bool high = (codec.mask & 0xFFFF'FFFFull) == 0;  // the field is in the upper half
  const int shift = codec.shift - (high ? 32 : 0);
  return {codec.offset / 4 + (high ? 1 : 0), std::max(0, -shift), std::max(0, shift),
          static_cast<uint32_t>(high ? codec.mask >> 32 : codec.mask)};
}

// One column's pixels are assembled as planes, one per 32-bit word of the pixel: each channel is
// one contiguous pass over its rows into its plane (vectorized: pixel_kernels.h), then one pass
// interleaves the planes into pixels and a single copy writes them. Read-modify-write of the
// packet's own bytes would instead stall store forwarding on overlapping words, and 64-bit words
// would halve the lanes.
void encode_rows(const packet_detail::FormatCodecs& impl, const ChannelValues& values, uint8_t* pixels) {
  assert(impl.pixel_bytes % 4 == 0 && impl.pixel_bytes / 4 <= packet_detail::kMaxPixelWords);
  const auto height = static_cast<size_t>(impl.format.pixels_per_column);
  std::array<packet_detail::WordLane, kChannelFieldCount> lanes;
  for (size_t k = 0; k < impl.channels.size(); ++k) {
    lanes[k] = word_lane(impl.channels[k].codec);
#ifndef NDEBUG
    for (size_t row = 0; row < height; ++row) {
      assert(impl.channels[k].codec.fits(values[k][row]) && "channel value wider than its packet field");
    }
#endif
  }
  static_assert(static_cast<int>(packet_detail::kMaxPixelRows) == kMaxPixelsPerColumn);
  alignas(64) uint32_t interleaved[packet_detail::kMaxPixelRows * packet_detail::kMaxPixelWords];
  packet_detail::assemble_pixels(values.data(), lanes.data(), impl.channels.size(), impl.pixel_bytes / 4, height,
                                 interleaved);
  std::memcpy(pixels, interleaved, height * impl.pixel_bytes);
}

void encode_pixels(const packet_detail::FormatCodecs& impl, const Scan& scan, int index, int m,
                   std::span<uint8_t> out) {
  ChannelValues values{};
  for (size_t k = 0; k < impl.channels.size(); ++k) {
    assert(scan.has(impl.channels[k].field));
    values[k] = scan.column(impl.channels[k].field, m).data();
  }
  uint8_t* pixels = out.data() + impl.pixel_start(index, 0);
  assert(impl.pixel_start(index, impl.format.pixels_per_column) <= out.size());
  encode_rows(impl, values, pixels);
}

void encode_column(const packet_detail::FormatCodecs& impl, const PacketHeader& header, const Scan& scan, int index,
                   int m, std::span<uint8_t> out) {
  const auto column = out.subspan(impl.column_start(index));
  for (const auto& [field, codec] : impl.column) codec.set(column, column_value(impl, field, header, scan, m));
  encode_pixels(impl, scan, index, m, out);
}

// Every byte the pixel rows do not cover (packet header, column headers and footers, packet
// footer) to zero, so fields set by read-modify-write start clean and reserved bits stay 0;
// encode_rows writes every pixel byte itself, so the ~25 KB of pixels are not cleared first.
void zero_outside_pixels(const packet_detail::FormatCodecs& impl, std::span<uint8_t> out) {
  const size_t pixels = static_cast<size_t>(impl.format.pixels_per_column) * impl.pixel_bytes;
  size_t cleared = 0;  // bytes [0, cleared) are done
  for (int i = 0; i < impl.format.columns_per_packet; ++i) {
    const size_t first_pixel = impl.pixel_start(i, 0);
    std::fill(out.begin() + static_cast<std::ptrdiff_t>(cleared),
              out.begin() + static_cast<std::ptrdiff_t>(first_pixel), uint8_t{0});
    cleared = first_pixel + pixels;
  }
  std::fill(out.begin() + static_cast<std::ptrdiff_t>(cleared), out.end(), uint8_t{0});
}

}  // namespace

// Header values are truncated to their field widths, so a running frame counter wraps at 2^16
// (2^32 with the FUSA header) as the sensor's does (protocol doc 6.2).
void PacketFormat::encode(const PacketHeader& header, const Scan& scan, int first_column, std::span<uint8_t> out,
                          FooterKind footer) const {
  const Impl& impl = *impl_;
  const int cpp = impl.format.columns_per_packet;
  assert(out.size() == impl.packet_size);
  assert(scan.width == impl.format.columns_per_frame && scan.height == impl.format.pixels_per_column);
  assert(first_column >= 0 && first_column + cpp <= scan.width);
  zero_outside_pixels(impl, out);
  for (const auto& [field, codec] : impl.header) {
    codec.set(out, packet_detail::header_value(header, field) & codec.max_value());
  }
  for (int i = 0; i < cpp; ++i) encode_column(impl, header, scan, i, first_column + i, out);
  if (impl.crc_footer) packet_detail::write_footer(out, footer);
}

}  // namespace lidartwin

namespace lidartwin {

bool PacketFormat::has_crc() const { return impl_->crc_footer; }

void PacketFormat::set_frame_id(std::span<uint8_t> packet, uint32_t frame_id) const {
  const Impl& impl = *impl_;
  assert(packet.size() == impl.packet_size);
  const bool crc_was_valid =
      impl.crc_footer && packet_detail::classify_footer(packet) == std::pair{FooterKind::kCrc64, true};
  for (const auto& [field, codec] : impl.header) {
    if (field == packet_detail::HeaderField::kFrameId) codec.set(packet, frame_id & codec.max_value());
  }
  for (const auto& [field, codec] : impl.column) {
    if (field != ColumnField::kFrameId) continue;
    for (int i = 0; i < impl.format.columns_per_packet; ++i) {
      codec.set(packet.subspan(impl.column_start(i)), frame_id & 0xFFFF);
    }
  }
  if (crc_was_valid) packet_detail::write_footer(packet, FooterKind::kCrc64);
}

}  // namespace lidartwin
