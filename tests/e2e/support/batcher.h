#pragma once
// Scan assembly exactly as the SDK-0.16 ScanBatcher does it (protocol doc 6.5), over the packets a
// client receives, plus the checks the e2e tests make on every assembled scan.
#include <chrono>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "e2e/support/udp_socket.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/frame/packet_plan.h"

namespace lidartwin::e2e {

struct AssembledScan {
  Scan scan;
  uint32_t frame_id = 0;
  size_t packets = 0;
  bool complete = false;  // released because every expected packet arrived
  std::set<uint32_t> init_ids;
  std::set<uint64_t> prod_sns;
};

class Batcher {
 public:
  explicit Batcher(const Metadata& metadata)
      : format_(metadata.format), expected_(static_cast<size_t>(format_.packets_per_frame())) {}

  const PacketFormat& format() const { return format_; }
  size_t expected_packets() const { return expected_; }
  size_t wrong_size = 0;     // dropped like read_lidar_packet does (1 item 9)
  size_t undecodable = 0;

  // One lidar datagram; returns the scan it finished, if any.
  std::optional<AssembledScan> add(std::span<const uint8_t> bytes) {
    if (bytes.size() != format_.lidar_packet_size()) {
      ++wrong_size;
      return std::nullopt;
    }
    Scan probe(format_.format());
    std::string error;
    const auto decoded = format_.decode(bytes, probe, &error);
    if (!decoded) {
      ++undecodable;
      return std::nullopt;
    }
    const uint32_t frame_id = decoded->header.frame_id;
    if (finished_ && (frame_id == *finished_ || frame_id + 1 == *finished_)) return std::nullopt;  // late
    std::optional<AssembledScan> released;
    if (open_ && open_->frame_id != frame_id) released = release();
    if (!open_) start(frame_id);
    format_.decode(bytes, open_->scan, &error);
    ++open_->packets;
    open_->init_ids.insert(decoded->header.init_id);
    open_->prod_sns.insert(decoded->header.prod_sn);
    if (open_->packets >= expected_) {
      open_->complete = true;
      return release();
    }
    return released;
  }

 private:
  void start(uint32_t frame_id) {
    open_ = AssembledScan{Scan(format_.format()), frame_id, 0, false, {}, {}};
  }
  std::optional<AssembledScan> release() {
    finished_ = open_->frame_id;
    auto scan = std::move(open_);
    open_.reset();
    return scan;
  }

  PacketFormat format_;
  size_t expected_;
  std::optional<AssembledScan> open_;
  std::optional<uint32_t> finished_;
};

// Receives until `count` scans were released (the first, possibly partial one, is skipped) or the
// timeout passes. Checks the source address of every datagram when `source` is given.
inline std::vector<AssembledScan> receive_scans(UdpSocket& socket, Batcher& batcher, size_t count,
                                                std::chrono::seconds timeout, const std::string& source = "") {
  std::vector<AssembledScan> scans;
  bool first = true;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (scans.size() < count && std::chrono::steady_clock::now() < deadline) {
    auto datagram = socket.receive(std::chrono::milliseconds(1000));
    if (!datagram) continue;
    if (!source.empty()) {
      EXPECT_EQ(datagram->source_ip, source);
    }
    auto scan = batcher.add(datagram->bytes);
    if (!scan) continue;
    if (first) {
      first = false;  // we may have joined mid-frame
      continue;
    }
    scans.push_back(std::move(*scan));
  }
  return scans;
}

inline int window_columns(const LidarDataFormat& format) {
  int n = 0;
  for (int m = 0; m < format.columns_per_frame; ++m) n += column_in_window(format.column_window, m) ? 1 : 0;
  return n;
}

// Every scan complete, every window column valid, frame_ids consecutive, ids equal to the
// metadata's (1 items 10-11), timestamps non-zero and rising (6.3).
inline void expect_complete_scans(const std::vector<AssembledScan>& scans, const Metadata& metadata, size_t count) {
  ASSERT_EQ(scans.size(), count) << "scans received";
  const auto& format = metadata.format;
  const uint64_t prod_sn = std::stoull(metadata.sensor_info.prod_sn);
  const bool legacy = format.udp_profile_lidar == UdpProfileLidar::kLegacy;
  const uint32_t modulus_mask = uses_fusa_header(format) ? 0xFFFF'FFFFu : 0xFFFFu;
  uint64_t previous_ts = 0;
  for (size_t i = 0; i < scans.size(); ++i) {
    const auto& s = scans[i];
    EXPECT_TRUE(s.complete) << "frame " << s.frame_id << ": " << s.packets << " packets";
    if (i > 0) {
      EXPECT_EQ(s.frame_id, (scans[i - 1].frame_id + 1) & modulus_mask);
    }
    if (!legacy) {
      EXPECT_EQ(s.init_ids, std::set<uint32_t>{metadata.sensor_info.initialization_id});
      EXPECT_EQ(s.prod_sns, std::set<uint64_t>{prod_sn});
    }
    int valid = 0;
    for (int m = 0; m < format.columns_per_frame; ++m) {
      if (!column_in_window(format.column_window, m)) continue;
      const auto column = static_cast<size_t>(m);
      valid += (s.scan.status[column] & 1u) ? 1 : 0;
      const uint64_t ts = s.scan.timestamp_ns[column];
      EXPECT_GT(ts, previous_ts) << "frame " << s.frame_id << " column " << m;
      previous_ts = ts;
    }
    EXPECT_EQ(valid, window_columns(format)) << "frame " << s.frame_id;
  }
}

inline Metadata parse(const nlohmann::json& document) { return parse_metadata(document, "GET sensor/metadata"); }

}  // namespace lidartwin::e2e
