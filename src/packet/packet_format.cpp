// Building a PacketFormat: validate the data format, resolve the tables into codecs, derive sizes
// (protocol doc 4.1).
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/packet/imu_packet.h"
#include "packet/packet_format_impl.h"

namespace lidartwin {
namespace {

using packet_detail::FieldCodec;

constexpr size_t kMaxUdpPayload = 65535;
constexpr int kMaxColumnsPerPacket = 64;
constexpr int kMaxColumnsPerFrame = 65536;  // measurement_id is a u16

[[noreturn]] void fail(const std::string& key, const std::string& expected, int64_t got) {
  throw InputError("lidar_data_format." + key + ": must be " + expected + ", got " + std::to_string(got));
}

void validate_shape(const LidarDataFormat& f) {
  if (static_cast<size_t>(f.udp_profile_lidar) >= udp_profile_lidar_names().size()) {
    fail("udp_profile_lidar", "a supported profile", static_cast<int>(f.udp_profile_lidar));
  }
  if (f.pixels_per_column < 1 || f.pixels_per_column > kMaxPixelsPerColumn) {
    fail("pixels_per_column", "1.." + std::to_string(kMaxPixelsPerColumn), f.pixels_per_column);
  }
  if (f.columns_per_packet < 1 || f.columns_per_packet > kMaxColumnsPerPacket) {
    fail("columns_per_packet", "1..64", f.columns_per_packet);
  }
  if (f.columns_per_frame < 1 || f.columns_per_frame > kMaxColumnsPerFrame) {
    fail("columns_per_frame", "1..65536", f.columns_per_frame);
  }
  if (f.columns_per_frame % f.columns_per_packet != 0) {
    fail("columns_per_frame", "a multiple of columns_per_packet " + std::to_string(f.columns_per_packet),
         f.columns_per_frame);
  }
  for (int i = 0; i < 2; ++i) {
    const int c = f.column_window[static_cast<size_t>(i)];
    if (c < 0 || c >= f.columns_per_frame) {
      fail("column_window[" + std::to_string(i) + "]", "0.." + std::to_string(f.columns_per_frame - 1), c);
    }
  }
}

// Protocol doc 5.1 and 5.2.
size_t imu_size(const LidarDataFormat& f) {
  switch (f.udp_profile_imu) {
    case UdpProfileImu::kLegacy: return kLegacyImuPacketSize;
    case UdpProfileImu::kOff: return 0;
    case UdpProfileImu::kAccel32Gyro32Nmea: {
      const int n = f.imu_measurements_per_packet;
      if (n < 1 || n > kMaxImuMeasurementsPerPacket) {
        fail("imu_measurements_per_packet",
             "1.." + std::to_string(kMaxImuMeasurementsPerPacket) + " for ACCEL32_GYRO32_NMEA", n);
      }
      return nmea_imu_packet_size(n);
    }
  }
  return 0;
}

void resolve_codecs(packet_detail::FormatCodecs& impl, const packet_detail::ProfileSpec& profile) {
  const packet_detail::PacketLayout& layout = *profile.layout;
  if (layout.packet_header_bytes > 0) {
    for (const auto& spec : packet_detail::header_spec(impl.header_type)) {
      impl.header.push_back({spec.field, FieldCodec::from(spec.bits)});
    }
  }
  for (const auto& spec : layout.column_header) impl.column.push_back({spec.field, FieldCodec::from(spec.bits)});
  const int footer_start = layout.column_header_bytes + profile.pixel_bytes * impl.format.pixels_per_column;
  for (const auto& spec : layout.column_footer) {
    impl.column.push_back({spec.field, FieldCodec::from(spec.bits, footer_start)});
  }
  for (const auto& spec : profile.channels) {
    const FieldCodec codec = FieldCodec::in_word(spec.bits);
    impl.channels.push_back({spec.field, codec});
    impl.channel_by_field[static_cast<size_t>(spec.field)] = codec;
  }
}

void build(const LidarDataFormat& format, packet_detail::FormatCodecs* impl) {
  validate_shape(format);
  const packet_detail::ProfileSpec& profile = packet_detail::profile_spec(format.udp_profile_lidar);
  const packet_detail::PacketLayout& layout = *profile.layout;
  impl->format = format;
  impl->header_type = packet_header_type(format);
  impl->pixel_bytes = static_cast<size_t>(profile.pixel_bytes);
  impl->columns_offset = static_cast<size_t>(layout.packet_header_bytes);
  impl->pixels_offset = static_cast<size_t>(layout.column_header_bytes);
  impl->column_size = static_cast<size_t>(layout.column_header_bytes + layout.column_footer_bytes) +
                      impl->pixel_bytes * static_cast<size_t>(format.pixels_per_column);
  impl->packet_size = static_cast<size_t>(layout.packet_header_bytes + layout.packet_footer_bytes) +
                      impl->column_size * static_cast<size_t>(format.columns_per_packet);
  if (impl->packet_size > kMaxUdpPayload) {
    throw InputError("lidar_data_format: a " + std::string(to_string(format.udp_profile_lidar)) + " packet of " +
                     std::to_string(format.columns_per_packet) + " columns x " +
                     std::to_string(format.pixels_per_column) + " pixels would be " +
                     std::to_string(impl->packet_size) + " bytes, more than a UDP datagram's 65535");
  }
  impl->imu_packet_size = imu_size(format);
  impl->crc_footer = layout.crc_footer;
  resolve_codecs(*impl, profile);
}

}  // namespace

PacketFormat::PacketFormat(const LidarDataFormat& format) {
  auto impl = std::make_shared<Impl>();
  build(format, impl.get());
  impl_ = std::move(impl);
}

const LidarDataFormat& PacketFormat::format() const { return impl_->format; }
size_t PacketFormat::lidar_packet_size() const { return impl_->packet_size; }
size_t PacketFormat::imu_packet_size() const { return impl_->imu_packet_size; }
size_t PacketFormat::column_size() const { return impl_->column_size; }

bool PacketFormat::has_channel(ChannelField field) const {
  return impl_->channel_by_field[static_cast<size_t>(field)].present();
}
uint32_t PacketFormat::channel_max(ChannelField field) const {
  return static_cast<uint32_t>(impl_->channel_by_field[static_cast<size_t>(field)].max_value());
}
uint32_t PacketFormat::channel_step(ChannelField field) const {
  const FieldCodec& codec = impl_->channel_by_field[static_cast<size_t>(field)];
  return codec.present() ? static_cast<uint32_t>(codec.step()) : 0;
}

bool PacketFormat::packet_in_window(int first_column) const {
  const LidarDataFormat& f = impl_->format;
  for (int m = first_column; m < first_column + f.columns_per_packet; ++m) {
    if (column_in_window(f.column_window, m)) return true;
  }
  return false;
}

// Counting packets directly; it agrees with the SDK's closed form (protocol doc 6.4), which the
// tests check on the real windows.
int PacketFormat::packets_per_frame() const {
  const LidarDataFormat& f = impl_->format;
  int count = 0;
  for (int first = 0; first < f.columns_per_frame; first += f.columns_per_packet) {
    if (packet_in_window(first)) ++count;
  }
  return count;
}

}  // namespace lidartwin
