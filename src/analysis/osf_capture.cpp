// OSF LidarScans -> the frames the analysis compares. A LidarScan is a frame as the SDK's batcher
// left it, so the conversion only restores what the file changed: PNG fields are stored
// destaggered (ZPNG ones are not), and which packets arrived is told by the per-packet timestamps.
#include "analysis/osf_capture.h"

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "lidartwin/error.h"
#include "lidartwin/packet/scan_batcher.h"
#include "lidartwin/pcap/osf.h"

namespace lidartwin::analysis_detail {
namespace {

namespace fs = std::filesystem;

std::optional<ChannelField> channel_of(OsfField field) {
  switch (field) {
    case OsfField::kRange: return ChannelField::kRange;
    case OsfField::kRange2: return ChannelField::kRange2;
    case OsfField::kSignal: return ChannelField::kSignal;
    case OsfField::kSignal2: return ChannelField::kSignal2;
    case OsfField::kReflectivity: return ChannelField::kReflectivity;
    case OsfField::kReflectivity2: return ChannelField::kReflectivity2;
    case OsfField::kNearIr: return ChannelField::kNearIr;
    case OsfField::kFlags: return ChannelField::kFlags;
    case OsfField::kFlags2: return ChannelField::kFlags2;
  }
  return std::nullopt;
}

Metadata metadata_of(const fs::path& osf, const OsfFileInfo& info, const fs::path& metadata_path) {
  if (!metadata_path.empty()) return load_metadata(metadata_path);
  const std::string source = osf.string() + " (its LidarSensor metadata)";
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(info.sensor_metadata);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: not JSON: {}", source, e.what()));
  }
  return parse_metadata(document, source);
}

// The image into the scan's column-major channel. The SDK destaggers by moving column m of row r to
// (m + pixel_shift_by_row[r]) mod W (ouster_core's destagger), so column m is found there.
void copy_into(const OsfImage& image, const std::vector<int>& shift, Scan& scan, ChannelField channel) {
  const int width = scan.width;
  for (int r = 0; r < scan.height; ++r) {
    const int s = image.destaggered ? ((shift[static_cast<size_t>(r)] % width) + width) % width : 0;
    const uint32_t* row = image.values.data() + static_cast<size_t>(r) * static_cast<size_t>(width);
    for (int m = 0; m < width; ++m) scan.at(channel, m, r) = row[(m + s) % width];
  }
}

BatchedFrame frame_of(const OsfScan& osf, const Metadata& metadata, size_t expected_packets) {
  const LidarDataFormat& format = metadata.format;
  BatchedFrame frame;
  frame.scan = Scan(format);
  Scan& scan = frame.scan;
  scan.timestamp_ns = osf.column_timestamp_ns;
  scan.status = osf.column_status;
  scan.header.frame_id = static_cast<uint32_t>(osf.frame_id);
  scan.header.init_id = metadata.sensor_info.initialization_id;
  scan.header.prod_sn = std::stoull("0" + metadata.sensor_info.prod_sn);
  for (const OsfImage& image : osf.images) {
    const std::optional<ChannelField> channel = channel_of(image.field);
    if (channel && scan.has(*channel)) copy_into(image, format.pixel_shift_by_row, scan, *channel);
  }
  // A packet arrived if any of its columns carries a timestamp, or, in a scan none of whose columns
  // does, if the writer stamped the packet. A writer may stamp every packet of a scan and keep the
  // columns' valid bits, although the recording stopped before some arrived: those columns carry
  // no timestamp, and are absent, not dark.
  const auto per_packet = static_cast<size_t>(format.columns_per_packet);
  const bool columns_stamped = std::ranges::any_of(scan.timestamp_ns, [](uint64_t t) { return t != 0; });
  for (size_t p = 0; p < scan.packet_received.size(); ++p) {
    uint64_t stamp = 0;
    for (size_t m = p * per_packet; stamp == 0 && m < (p + 1) * per_packet; ++m) stamp = scan.timestamp_ns[m];
    if (!columns_stamped && p < osf.packet_timestamp_ns.size()) stamp = osf.packet_timestamp_ns[p];
    scan.packet_received[p] = stamp;
    if (stamp != 0) ++frame.packets;
  }
  frame.frame_id = scan.header.frame_id;
  frame.complete = frame.packets >= expected_packets;
  frame.init_ids.insert(scan.header.init_id);
  frame.prod_sns.insert(scan.header.prod_sn);
  return frame;
}

// The scan must be the metadata's shape, or its pixels would land on the wrong beams.
void check_shape(const OsfScan& osf, const LidarDataFormat& format, const std::string& names) {
  if (osf.width != format.columns_per_frame || osf.height != format.pixels_per_column) {
    throw InputError(fmt::format("{}: its scans are {} columns x {} rows, the metadata says {} x {}", names, osf.width,
                                 osf.height, format.columns_per_frame, format.pixels_per_column));
  }
  const auto has_range = std::ranges::any_of(osf.images, [](const OsfImage& i) { return i.field == OsfField::kRange; });
  if (!has_range) throw InputError(names + ": its scans hold no RANGE field (saved with a field list without it?)");
}

// The profile's channels the scan does not carry, by the SDK's names.
std::vector<std::string> missing_fields(const OsfScan& osf, const LidarDataFormat& format) {
  LidarDataFormat one_pixel = format;  // a scan of the profile's channels, one pixel each
  one_pixel.columns_per_frame = one_pixel.pixels_per_column = one_pixel.columns_per_packet = 1;
  const Scan probe(one_pixel);
  std::vector<std::string> missing;
  for (const OsfField field : {OsfField::kRange, OsfField::kRange2, OsfField::kSignal, OsfField::kSignal2,
                               OsfField::kReflectivity, OsfField::kReflectivity2, OsfField::kNearIr}) {
    const bool held = std::ranges::any_of(osf.images, [&](const OsfImage& i) { return i.field == field; });
    if (!held && probe.has(*channel_of(field))) missing.push_back(to_string(field));
  }
  return missing;
}

}  // namespace

MeasuredCapture read_osf_capture(const fs::path& osf, const fs::path& metadata_path, size_t max_frames,
                                 size_t skip_frames) {
  OsfReader reader(osf);
  MeasuredCapture capture;
  capture.metadata = metadata_of(osf, reader.info(), metadata_path);
  capture.lidar_streams = reader.info().lidar_streams;
  const Metadata& metadata = capture.metadata;
  const std::string names = metadata_path.empty()
                                ? "--capture " + osf.string()
                                : fmt::format("--capture {} with --metadata {}", osf.string(), metadata_path.string());
  if (!metadata.undecodable_lidar_profile.empty()) {
    throw InputError(fmt::format("{}: the metadata's udp_profile_lidar {} is not one lidartwin reads", names,
                                 metadata.undecodable_lidar_profile));
  }
  if (metadata.format.pixel_shift_by_row.size() != static_cast<size_t>(metadata.format.pixels_per_column)) {
    throw InputError(names + ": the metadata's pixel_shift_by_row does not have one entry per row");
  }
  const size_t expected_packets = ScanBatcher(metadata.format).expected_packets();
  size_t scans = 0;
  while (auto scan = reader.next()) {
    check_shape(*scan, metadata.format, names);
    if (scans++ == 0) capture.missing_fields = missing_fields(*scan, metadata.format);
    BatchedFrame frame = frame_of(*scan, metadata, expected_packets);
    capture.counts.batched += frame.packets;
    for (const uint64_t stamp : frame.scan.timestamp_ns) {
      if (stamp != 0 && (capture.start_ns == 0 || stamp < capture.start_ns)) capture.start_ns = stamp;
    }
    if (capture.skipped_frames < skip_frames) {
      ++capture.skipped_frames;
      continue;
    }
    capture.frames.push_back(std::move(frame));
    if (max_frames != 0 && capture.frames.size() >= max_frames) break;
  }
  if (scans == 0) throw InputError(names + ": its lidar stream holds no scan");
  if (capture.frames.empty()) {
    throw InputError(fmt::format("--capture {}: --skip-frames {} leaves no frame (the capture has {})", osf.string(),
                                 skip_frames, scans));
  }
  return capture;
}

}  // namespace lidartwin::analysis_detail
