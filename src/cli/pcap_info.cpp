#include "cli/pcap_info.h"

#include <algorithm>
#include <charconv>

#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan_batcher.h"

namespace lidartwin::cli {
namespace {

uint16_t config_port(const Metadata& metadata, const char* key) {
  const auto it = metadata.config_params.find(key);
  if (it == metadata.config_params.end() || !it->is_number_integer()) return 0;
  const int64_t port = it->get<int64_t>();
  return port > 0 && port <= 65535 ? static_cast<uint16_t>(port) : 0;
}

uint64_t serial_number(const std::string& prod_sn) {
  uint64_t sn = 0;
  std::from_chars(prod_sn.data(), prod_sn.data() + prod_sn.size(), sn);
  return sn;
}

// Lidar packets are the datagrams of exactly the packet size (protocol doc 1, item 9) on the
// metadata's port; captures replayed to another port (windowed_frame*.pcap) fall back to any port.
std::vector<const UdpDatagram*> lidar_datagrams(const std::vector<UdpDatagram>& datagrams, LidarSummary& summary) {
  std::vector<const UdpDatagram*> selected;
  for (bool any_port : {false, true}) {
    for (const UdpDatagram& d : datagrams) {
      if (d.payload.size() == summary.packet_size && (any_port || d.dst_port == summary.port)) selected.push_back(&d);
    }
    if (!selected.empty()) {
      summary.port_from_metadata = !any_port;
      if (any_port) summary.port = selected.front()->dst_port;
      break;
    }
  }
  return selected;
}

void tally_footer(FooterKind footer, LidarSummary& summary) {
  if (footer == FooterKind::kCrc64) ++summary.crc_ok;
  if (footer == FooterKind::kOther) ++summary.crc_failed;
  if (footer == FooterKind::kFw2Marker || footer == FooterKind::kZero) ++summary.without_crc;
}

// A frame's valid columns (status bit 0), their pixels and returns; frames repeated in a capture
// (a frame_id that comes round again) add to the same tally.
void tally_frame(const BatchedFrame& batched, FrameTally& frame) {
  const Scan& scan = batched.scan;
  if (frame.valid_columns.empty()) frame.valid_columns.assign(static_cast<size_t>(scan.width), false);
  for (int m = 0; m < scan.width; ++m) {
    if (!scan.column_valid(m)) continue;
    frame.valid_columns[static_cast<size_t>(m)] = true;
    const auto range = scan.column(ChannelField::kRange, m);
    frame.pixels += range.size();
    frame.returns +=
        static_cast<uint64_t>(std::count_if(range.begin(), range.end(), [](uint32_t r) { return r != 0; }));
    if (!scan.has(ChannelField::kRange2)) continue;
    const auto range2 = scan.column(ChannelField::kRange2, m);
    frame.second_returns +=
        static_cast<uint64_t>(std::count_if(range2.begin(), range2.end(), [](uint32_t r) { return r != 0; }));
  }
}

}  // namespace

PortSizeCounts count_datagrams(const std::vector<UdpDatagram>& datagrams) {
  PortSizeCounts counts;
  for (const UdpDatagram& d : datagrams) ++counts[{d.dst_port, d.payload.size()}];
  return counts;
}

LidarSummary summarize_lidar(const std::vector<UdpDatagram>& datagrams, const Metadata& metadata) {
  const PacketFormat format(metadata.format);
  LidarSummary summary;
  summary.port = config_port(metadata, "udp_port_lidar");
  summary.packet_size = format.lidar_packet_size();
  summary.dual = format.has_channel(ChannelField::kRange2);
  const uint16_t imu_port = config_port(metadata, "udp_port_imu");
  for (const UdpDatagram& d : datagrams) {
    if (d.dst_port == imu_port && d.payload.size() == format.imu_packet_size()) ++summary.imu_packets;
  }
  // The SDK drops packets of another prod_sn or init_id (non-legacy headers name their sensor).
  ScanBatcher batcher(metadata.format,
                      SensorIds{metadata.sensor_info.initialization_id, serial_number(metadata.sensor_info.prod_sn)});
  const auto tally = [&summary](const std::optional<BatchedFrame>& frame) {
    if (frame) tally_frame(*frame, summary.frames[frame->frame_id]);
  };
  for (const UdpDatagram* d : lidar_datagrams(datagrams, summary)) {
    const size_t batched = batcher.counts().batched;
    tally(batcher.add(d->payload));
    if (batcher.counts().batched > batched) tally_footer(batcher.last_packet()->footer, summary);
  }
  tally(batcher.flush());
  const ScanBatcher::Counts& counts = batcher.counts();
  summary.packets = counts.batched;
  summary.foreign = counts.foreign;
  summary.malformed = counts.undecodable;
  summary.late = counts.late;
  summary.first_error = batcher.first_error();
  return summary;
}

}  // namespace lidartwin::cli
