#pragma once
// A capture as the analysis reads it: the sensor's metadata and the frames its lidar packets make,
// batched as the Ouster SDK batches them.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/scan_batcher.h"

namespace lidartwin {

struct MeasuredCapture {
  Metadata metadata;
  std::vector<BatchedFrame> frames;  // in capture order; only frames with at least one packet
  size_t datagrams = 0;              // UDP datagrams in the capture
  ScanBatcher::Counts counts;        // what the batcher did with them
  size_t skipped_frames = 0;         // frames read before `frames` (held out for another use)
  uint64_t start_ns = 0;             // the first valid column timestamp of the capture, skipped frames included
  size_t lidar_streams = 1;          // an OSF file's sensors (LidarScan streams); the first is read
  // Channels of the metadata's profile that an OSF file does not hold (saved with a field list),
  // left zero: "SIGNAL", "NEAR_IR"...
  std::vector<std::string> missing_fields;
  size_t cut_short_record = 0;  // a pcap that ends inside this record (PcapStats); 0: whole
};

// Reads up to max_frames frames (0: all) of a pcap, or of an OSF recording (ouster-cli's; told by
// its header, whatever its name), whose LidarScans become the frames; an OSF file carries its
// metadata, so metadata_path may be empty for one (given, it replaces the file's). Packets of another sensor or session
// (init_id, prod_sn other than the metadata's) are left out as the SDK leaves them out. Throws InputError naming the
// capture and the metadata when no datagram is a lidar packet of the metadata's format (a capture
// of another mode or profile, or of another sensor), or the metadata's lidar output is off.
// skip_frames: frames left out at the start (a fit's frames, when comparing on held-out ones).
MeasuredCapture read_capture(const std::filesystem::path& capture, const std::filesystem::path& metadata_path,
                             size_t max_frames = 0, size_t skip_frames = 0);

// The columns of the capture's frames whose packets never arrived (lost, outside an azimuth
// window, or after a recording stopped mid-frame): absent, not dark. compare leaves them out
// and says how many.
size_t columns_not_received(const MeasuredCapture& capture);

}  // namespace lidartwin
