#pragma once
// Lidar packets -> frames of columns, as the Ouster SDK's ScanBatcher assembles them (protocol doc
// 6.5): the one batcher of the project, for pcap-info, the analysis and the tests' SDK-like clients.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <set>
#include <span>
#include <string>

#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"

namespace lidartwin {

struct BatchedFrame {
  Scan scan;  // columns of packets that did not arrive stay zero (no points)
  uint32_t frame_id = 0;
  size_t packets = 0;           // lidar packets batched into it
  bool complete = false;        // every packet the window sends arrived (released at once)
  std::set<uint32_t> init_ids;  // as the packets carried them (one for a healthy stream)
  std::set<uint64_t> prod_sns;
};

// Which packets belong to the sensor: the SDK drops non-legacy packets whose init_id or prod_sn
// differ from the metadata's (protocol doc 1 items 10-11). Unset: keep every packet.
struct SensorIds {
  uint32_t init_id = 0;
  uint64_t prod_sn = 0;
};

class ScanBatcher {
 public:
  // Throws InputError naming a format the packet module cannot decode.
  explicit ScanBatcher(const LidarDataFormat& format, std::optional<SensorIds> sensor = std::nullopt);

  // One lidar datagram. Returns the frame it finished, if any:
  // - a packet of the open frame completes it when the last packet the window sends arrives;
  // - a packet of another frame (or, as SDK 1.0, another init_id) releases the open frame as it is
  //   and starts the next one;
  // - a packet of the frame just released, or of the one before it, is late and dropped;
  // - a datagram of another size, one that does not decode, and (with SensorIds) a packet of
  //   another sensor or session are dropped and counted.
  std::optional<BatchedFrame> add(std::span<const uint8_t> datagram);
  // The open frame, as it is (end of a capture). Then the batcher starts afresh.
  std::optional<BatchedFrame> flush();

  const PacketFormat& format() const { return format_; }
  size_t expected_packets() const { return expected_; }

  struct Counts {
    size_t batched = 0;      // packets that went into a frame
    size_t wrong_size = 0;   // not the lidar packet size (dropped like the SDK's read_lidar_packet)
    size_t undecodable = 0;  // right size, but the packet module refused it (see first_error)
    size_t foreign = 0;      // another sensor's prod_sn or another session's init_id
    size_t late = 0;         // for a frame already released
  };
  const Counts& counts() const { return counts_; }
  const std::string& first_error() const { return first_error_; }
  // The last packet that went into a frame, decoded (its footer kind, CRC check, first column).
  const std::optional<PacketFormat::Decoded>& last_packet() const { return last_packet_; }

 private:
  bool late(uint32_t frame_id) const;
  std::optional<BatchedFrame> release();

  PacketFormat format_;
  size_t expected_;
  std::optional<SensorIds> sensor_;
  uint32_t frame_id_mask_;
  Scan probe_;  // where a packet is decoded first, to learn its frame before it joins one
  std::optional<BatchedFrame> open_;
  std::optional<uint32_t> released_id_;
  Counts counts_;
  std::string first_error_;
  std::optional<PacketFormat::Decoded> last_packet_;
};

}  // namespace lidartwin
