// Capture + metadata -> the frames the analysis compares, through the project's one ScanBatcher.
#include "lidartwin/analysis/measured_capture.h"

#include <algorithm>
#include <map>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "analysis/osf_capture.h"
#include "lidartwin/error.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/pcap/osf.h"
#include "lidartwin/pcap/pcap.h"

namespace lidartwin {
namespace {

// "sizes 3392 (1200 datagrams), 48 (300)": what the capture holds, for the error that says it is
// not what the metadata describes.
std::string size_histogram(const std::map<size_t, size_t>& sizes) {
  std::vector<std::string> parts;
  for (const auto& [size, count] : sizes) {
    parts.push_back(fmt::format("{} bytes ({} datagram{})", size, count, count == 1 ? "" : "s"));
    if (parts.size() == 6) break;
  }
  return fmt::format("{}", fmt::join(parts, ", "));
}

}  // namespace

MeasuredCapture read_capture(const std::filesystem::path& pcap, const std::filesystem::path& metadata_path,
                             size_t max_frames, size_t skip_frames) {
  if (read_as_osf(pcap)) return analysis_detail::read_osf_capture(pcap, metadata_path, max_frames, skip_frames);
  if (metadata_path.empty()) {
    throw InputError("--capture " + pcap.string() + ": give --metadata (the capture's sensor metadata JSON)");
  }
  MeasuredCapture capture;
  capture.metadata = load_metadata(metadata_path);
  const Metadata& metadata = capture.metadata;
  const std::string names = fmt::format("--capture {} with --metadata {}", pcap.string(), metadata_path.string());
  if (!metadata.undecodable_lidar_profile.empty()) {
    throw InputError(fmt::format("{}: the metadata's udp_profile_lidar {} is not one lidartwin decodes", names,
                                 metadata.undecodable_lidar_profile));
  }
  if (!metadata.lidar_enabled()) throw InputError(names + ": the metadata says the sensor sent no lidar packets");
  std::optional<SensorIds> ids;
  if (metadata.format.udp_profile_lidar != UdpProfileLidar::kLegacy) {
    ids = SensorIds{metadata.sensor_info.initialization_id, std::stoull("0" + metadata.sensor_info.prod_sn)};
  }
  ScanBatcher batcher(metadata.format, ids);
  PcapReader reader(pcap);
  std::map<size_t, size_t> sizes;
  const auto keep = [&](std::optional<BatchedFrame> frame) {
    if (!frame) return;
    for (size_t m = 0; m < frame->scan.timestamp_ns.size(); ++m) {
      const uint64_t stamp = frame->scan.timestamp_ns[m];
      if (stamp != 0 && (capture.start_ns == 0 || stamp < capture.start_ns)) capture.start_ns = stamp;
    }
    if (capture.skipped_frames < skip_frames) {
      ++capture.skipped_frames;
      return;
    }
    if (max_frames == 0 || capture.frames.size() < max_frames) capture.frames.push_back(std::move(*frame));
  };
  while (auto datagram = reader.next()) {
    ++capture.datagrams;
    ++sizes[datagram->payload.size()];
    keep(batcher.add(datagram->payload));
    if (max_frames != 0 && capture.frames.size() >= max_frames) break;
  }
  keep(batcher.flush());
  capture.counts = batcher.counts();
  capture.cut_short_record = reader.stats().cut_short_record;
  if (capture.frames.empty() && capture.skipped_frames > 0 && capture.skipped_frames == skip_frames) {
    throw InputError(fmt::format("--capture {}: --skip-frames {} leaves no frame (the capture has {})", pcap.string(),
                                 skip_frames, capture.skipped_frames));
  }
  if (capture.frames.empty()) {
    const PacketFormat& format = batcher.format();
    std::string why = fmt::format(
        "none of its {} UDP datagrams is a lidar packet of the metadata's format ({} {}, "
        "{} bytes per packet); the capture has {}",
        capture.datagrams, to_string(metadata.format.udp_profile_lidar), metadata.format.columns_per_frame,
        format.lidar_packet_size(), size_histogram(sizes));
    if (capture.counts.foreign > 0) {
      why = fmt::format(
          "its {} lidar packets come from another sensor or session (init_id/prod_sn differ from the "
          "metadata's {}/{})",
          capture.counts.foreign, metadata.sensor_info.initialization_id, metadata.sensor_info.prod_sn);
    } else if (capture.counts.undecodable > 0) {
      why = fmt::format("its lidar-sized packets do not decode: {}", batcher.first_error());
    }
    throw InputError(names + ": " + why);
  }
  // A capture of another lidar mode with the same packet size decodes, into frames that never
  // fill (half of every 1024-wide frame from a 512 capture): refuse it rather than compare half
  // frames. Real captures cut their first and last frames short, so one complete frame suffices.
  size_t fullest = 0;
  for (const BatchedFrame& frame : capture.frames) {
    if (frame.complete) return capture;
    fullest = std::max(fullest, frame.packets);
  }
  throw InputError(
      fmt::format("{}: none of its {} frames is complete for the metadata's lidar mode {}x{} ({} packets "
                  "per frame; the fullest has {}): a capture of another lidar mode or column window?",
                  names, capture.frames.size(), metadata.format.columns_per_frame, metadata.format.fps,
                  batcher.expected_packets(), fullest));
}

size_t columns_not_received(const MeasuredCapture& capture) {
  size_t columns = 0;
  for (const BatchedFrame& frame : capture.frames) {
    for (const uint64_t received : frame.scan.packet_received) {
      if (received == 0) columns += static_cast<size_t>(capture.metadata.format.columns_per_packet);
    }
  }
  return columns;
}

}  // namespace lidartwin
