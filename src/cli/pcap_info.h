#pragma once
// What a capture holds: datagrams by port and size, and with metadata, the lidar stream decoded
// with the packet module (frames, columns, valid pixels, CRCs). Pure: no printing, no files.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pcap/pcap.h"

namespace lidartwin::cli {

using PortSizeCounts = std::map<std::pair<uint16_t, size_t>, size_t>;  // (dst port, bytes) -> count
PortSizeCounts count_datagrams(const std::vector<UdpDatagram>& datagrams);

struct FrameTally {
  std::vector<bool> valid_columns;  // status bit 0, by measurement id
  uint64_t pixels = 0;              // pixels of valid columns
  uint64_t returns = 0;             // ... whose first range is non-zero
  uint64_t second_returns = 0;      // ... whose second range is non-zero (dual-return profiles)
};

struct LidarSummary {
  uint16_t port = 0;               // where lidar packets were taken from
  bool port_from_metadata = true;  // false: the metadata's port had none, any port was used
  size_t packet_size = 0;
  size_t packets = 0;  // decoded lidar packets of this sensor
  size_t foreign = 0;  // right size, but prod_sn/init_id of another sensor or session
  size_t malformed = 0;
  size_t late = 0;  // for a frame already assembled (the SDK drops them)
  std::string first_error;
  size_t crc_ok = 0;  // footers with a matching CRC-64
  size_t crc_failed = 0;
  size_t without_crc = 0;                 // FW 2 marker or zero footers (protocol doc 4.5)
  bool dual = false;                      // the profile carries second returns
  std::map<uint32_t, FrameTally> frames;  // by frame_id
  size_t imu_packets = 0;                 // on udp_port_imu, of the IMU packet size
};

// Requires metadata.lidar_enabled(). Throws InputError if the format cannot be decoded.
LidarSummary summarize_lidar(const std::vector<UdpDatagram>& datagrams, const Metadata& metadata);

}  // namespace lidartwin::cli
