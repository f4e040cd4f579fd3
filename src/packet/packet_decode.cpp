// One lidar packet -> Scan. Packets are hostile input: everything is checked before the scan is
// touched, and every read stays inside the packet (its size is checked first, and the codecs were
// built for exactly that size).
#include <algorithm>
#include <array>
#include <cassert>
#include <cstring>
#include <string>

#include "packet/footer.h"
#include "packet/packet_format_impl.h"

namespace lidartwin {
namespace {

using packet_detail::ColumnField;

std::optional<PacketFormat::Decoded> failure(std::string* error, std::string message) {
  if (error != nullptr) *error = "lidar packet: " + std::move(message);
  return std::nullopt;
}

std::string shape_of(int width, int height) { return std::to_string(width) + "x" + std::to_string(height); }

// The caller's scan must have this format's shape and channels.
std::optional<std::string> scan_mismatch(const packet_detail::FormatCodecs& impl, const Scan& scan) {
  const LidarDataFormat& f = impl.format;
  const auto packets = static_cast<size_t>(f.columns_per_frame / f.columns_per_packet);
  const auto w = static_cast<size_t>(f.columns_per_frame);
  if (scan.width != f.columns_per_frame || scan.height != f.pixels_per_column || scan.timestamp_ns.size() != w ||
      scan.status.size() != w || scan.packet_received.size() != packets) {
    return "scan is " + shape_of(scan.width, scan.height) + ", the packet format is " +
           shape_of(f.columns_per_frame, f.pixels_per_column);
  }
  for (const auto& channel : impl.channels) {
    if (scan.channels[static_cast<size_t>(channel.field)].size() != w * static_cast<size_t>(scan.height)) {
      return "scan has no " + std::string(to_string(channel.field)) + " channel of " +
             shape_of(scan.width, scan.height);
    }
  }
  return std::nullopt;
}

uint64_t column_field(const packet_detail::FormatCodecs& impl, std::span<const uint8_t> packet, int index,
                      ColumnField field) {
  for (const auto& c : impl.column) {
    if (c.field == field) return c.codec.get(packet.subspan(impl.column_start(index)));
  }
  return 0;
}

using ChannelValues = std::array<uint32_t*, kChannelFieldCount>;

// The mirror of encode_rows (packet_encode.cpp): pixels are copied into 64-bit words with
// fixed-size moves, then each field is extracted over all rows in one tight loop.
template <size_t kPixelBytes>
void decode_rows(const packet_detail::FormatCodecs& impl, const uint8_t* pixels, const ChannelValues& values) {
  constexpr size_t kWords = (kPixelBytes + 7) / 8;
  const auto height = static_cast<size_t>(impl.format.pixels_per_column);
  std::array<std::array<uint64_t, kWords>, kMaxPixelsPerColumn> words;
  for (size_t row = 0; row < height; ++row) {
    words[row] = {};
    std::memcpy(words[row].data(), pixels + row * kPixelBytes, kPixelBytes);
  }
  for (size_t k = 0; k < impl.channels.size(); ++k) {
    const packet_detail::FieldCodec codec = impl.channels[k].codec;
    const size_t w = codec.offset / 8;
    uint32_t* v = values[k];
    for (size_t row = 0; row < height; ++row) v[row] = static_cast<uint32_t>(codec.extract(words[row][w]));
  }
}

void decode_pixels(const packet_detail::FormatCodecs& impl, std::span<const uint8_t> packet, int index, int m,
                   Scan& scan) {
  ChannelValues values{};
  for (size_t k = 0; k < impl.channels.size(); ++k) values[k] = scan.column(impl.channels[k].field, m).data();
  const uint8_t* pixels = packet.data() + impl.pixel_start(index, 0);
  switch (impl.pixel_bytes) {
    case 4: return decode_rows<4>(impl, pixels, values);
    case 8: return decode_rows<8>(impl, pixels, values);
    case 12: return decode_rows<12>(impl, pixels, values);
    case 16: return decode_rows<16>(impl, pixels, values);
    case 20: return decode_rows<20>(impl, pixels, values);
    case 24: return decode_rows<24>(impl, pixels, values);
    default: assert(false && "pixel size missing from the dispatch");
  }
}

void decode_column(const packet_detail::FormatCodecs& impl, std::span<const uint8_t> packet, int index, int m,
                   Scan& scan) {
  const auto column = packet.subspan(impl.column_start(index));
  const auto col = static_cast<size_t>(m);
  for (const auto& [field, codec] : impl.column) {
    if (field == ColumnField::kTimestamp) scan.timestamp_ns[col] = codec.get(column);
    if (field == ColumnField::kStatus) scan.status[col] = static_cast<uint32_t>(codec.get(column));
  }
  decode_pixels(impl, packet, index, m, scan);
}

std::string size_error(const packet_detail::FormatCodecs& impl, size_t size) {
  const LidarDataFormat& f = impl.format;
  return std::to_string(size) + " bytes, expected " + std::to_string(impl.packet_size) + " for " +
         std::string(to_string(f.udp_profile_lidar)) + " with " + std::to_string(f.pixels_per_column) + " pixels x " +
         std::to_string(f.columns_per_packet) + " columns";
}

// Header, first measurement id and footer; reads only, so a packet can be refused after it.
PacketFormat::Decoded decode_header(const packet_detail::FormatCodecs& impl, std::span<const uint8_t> packet) {
  PacketFormat::Decoded decoded;
  bool frame_id_in_header = false;
  for (const auto& [field, codec] : impl.header) {
    packet_detail::set_header_value(decoded.header, field, codec.get(packet));
    frame_id_in_header |= field == packet_detail::HeaderField::kFrameId;
  }
  // LEGACY carries frame_id per column; the SDK takes column 0's (protocol doc 4.2).
  if (!frame_id_in_header) {
    decoded.header.frame_id = static_cast<uint32_t>(column_field(impl, packet, 0, ColumnField::kFrameId));
  }
  decoded.first_measurement_id = static_cast<int>(column_field(impl, packet, 0, ColumnField::kMeasurementId));
  decoded.footer = FooterKind::kNone;
  if (impl.crc_footer) std::tie(decoded.footer, decoded.crc_ok) = packet_detail::classify_footer(packet);
  return decoded;
}

}  // namespace

std::optional<PacketFormat::Decoded> PacketFormat::decode(std::span<const uint8_t> packet, Scan& scan,
                                                          std::string* error) const {
  const Impl& impl = *impl_;
  const LidarDataFormat& f = impl.format;
  if (packet.size() != impl.packet_size) return failure(error, size_error(impl, packet.size()));
  if (auto mismatch = scan_mismatch(impl, scan)) return failure(error, *mismatch);
  const Decoded decoded = decode_header(impl, packet);
  if (decoded.header.packet_type != 1) {
    return failure(error, "packet_type " + std::to_string(decoded.header.packet_type) + ", expected 1 (lidar)");
  }

  if (std::all_of(scan.packet_received.begin(), scan.packet_received.end(), [](uint64_t n) { return n == 0; })) {
    scan.header = decoded.header;
  }
  for (int i = 0; i < f.columns_per_packet; ++i) {
    const auto m = static_cast<int>(column_field(impl, packet, i, ColumnField::kMeasurementId));
    if (m < f.columns_per_frame) decode_column(impl, packet, i, m, scan);  // the SDK drops m >= W (4.7)
  }
  if (decoded.first_measurement_id < f.columns_per_frame) {
    ++scan.packet_received[static_cast<size_t>(decoded.first_measurement_id / f.columns_per_packet)];
  }
  return decoded;
}

}  // namespace lidartwin
