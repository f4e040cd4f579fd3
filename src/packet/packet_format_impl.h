#pragma once
// PacketFormat's state: the tables of field_table.cpp resolved into codecs for one data format.
// Shared by packet_format.cpp (build, sizes), packet_encode.cpp and packet_decode.cpp. It is a
// namespace-level struct (PacketFormat::Impl only derives from it) so that helper functions in
// anonymous namespaces can take it; PacketFormat::Impl is private.
#include <array>
#include <cstddef>
#include <vector>

#include "lidartwin/packet/lidar_packet.h"
#include "packet/field_table.h"

namespace lidartwin {

inline constexpr int kMaxPixelsPerColumn = 128;
// Encoder ticks per revolution of a LEGACY column header (protocol doc 4.2).
inline constexpr uint64_t kEncoderTicksPerRevolution = 90112;

namespace packet_detail {

struct FormatCodecs {
  struct HeaderCodec {
    HeaderField field;
    FieldCodec codec;  // from the packet start
  };
  struct ColumnCodec {
    ColumnField field;
    FieldCodec codec;  // from the column start (footer fields included)
  };
  struct ChannelCodec {
    ChannelField field;
    FieldCodec codec;  // from the pixel start, offset a multiple of 8 (FieldCodec::in_word)
  };

  LidarDataFormat format;
  HeaderType header_type = HeaderType::kStandard;
  size_t pixel_bytes = 0;
  size_t columns_offset = 0;  // packet header bytes
  size_t pixels_offset = 0;   // column header bytes
  size_t column_size = 0;
  size_t packet_size = 0;
  size_t imu_packet_size = 0;
  bool crc_footer = false;
  std::vector<HeaderCodec> header;
  std::vector<ColumnCodec> column;
  std::vector<ChannelCodec> channels;
  std::array<FieldCodec, kChannelFieldCount> channel_by_field{};

  size_t column_start(int index_in_packet) const {
    return columns_offset + static_cast<size_t>(index_in_packet) * column_size;
  }
  size_t pixel_start(int index_in_packet, int row) const {
    return column_start(index_in_packet) + pixels_offset + static_cast<size_t>(row) * pixel_bytes;
  }
};

uint64_t header_value(const PacketHeader& header, HeaderField field);
void set_header_value(PacketHeader& header, HeaderField field, uint64_t value);
}  // namespace packet_detail

struct PacketFormat::Impl : packet_detail::FormatCodecs {};

}  // namespace lidartwin
