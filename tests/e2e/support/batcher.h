#pragma once
// Scans as an SDK client assembles them (the library's ScanBatcher, protocol doc 6.5) from the
// packets it receives, and the checks the e2e tests make on every assembled scan.
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
#include "lidartwin/packet/scan_batcher.h"

namespace lidartwin::e2e {

// Receives until `count` scans were released or the timeout passes. The first scan released is
// skipped (the socket may have joined mid-frame) unless `joined_mid_frame` is false: the batcher
// then goes on with a stream the caller has been reading. Checks the source address of every datagram when `source` is
// given.
inline std::vector<BatchedFrame> receive_scans(UdpSocket& socket, ScanBatcher& batcher, size_t count,
                                               std::chrono::seconds timeout, const std::string& source = "",
                                               bool joined_mid_frame = true) {
  std::vector<BatchedFrame> scans;
  bool first = joined_mid_frame;
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
inline void expect_complete_scans(const std::vector<BatchedFrame>& scans, const Metadata& metadata, size_t count) {
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
