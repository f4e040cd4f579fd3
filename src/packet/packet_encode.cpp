// Scan -> one lidar packet. Runs for every packet the daemon sends: no allocation, one pass.
#include <algorithm>
#include <cassert>
#include <cstring>

#include "packet/packet_format_impl.h"

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

void encode_column(const packet_detail::FormatCodecs& impl, const PacketHeader& header, const Scan& scan, int index,
                   int m, std::span<uint8_t> out) {
  const auto column = out.subspan(impl.column_start(index));
  for (const auto& [field, codec] : impl.column) codec.set(column, column_value(impl, field, header, scan, m));
  const int height = impl.format.pixels_per_column;
  for (const auto& [field, codec] : impl.channels) {
    const std::span<const uint32_t> values = scan.column(field, m);
    for (int row = 0; row < height; ++row) {
      codec.set(out.subspan(impl.pixel_start(index, row)), values[static_cast<size_t>(row)]);
    }
  }
}

void write_footer(std::span<uint8_t> out, FooterKind footer) {
  const auto body = out.first(out.size() - packet_detail::kCrcBytes);
  uint64_t word = 0;
  if (footer == FooterKind::kCrc64) word = crc64_xz(body);
  if (footer == FooterKind::kFw2Marker) word = kFw2FooterMarker;
  std::memcpy(out.data() + body.size(), &word, sizeof word);
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
  std::fill(out.begin(), out.end(), uint8_t{0});
  for (const auto& [field, codec] : impl.header) {
    codec.set(out, packet_detail::header_value(header, field) & codec.max_value());
  }
  for (int i = 0; i < cpp; ++i) encode_column(impl, header, scan, i, first_column + i, out);
  if (impl.crc_footer) write_footer(out, footer);
}

}  // namespace lidartwin
