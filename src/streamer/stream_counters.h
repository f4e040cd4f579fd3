#pragma once
// What the send clock counts, on the io thread only; the Streamer reports it once a second.
#include <cstdint>

#include "lidartwin/sensor/stream_config.h"
#include "streamer/lateness.h"

namespace lidartwin::streamer_detail {

// A packet sent more than this after its deadline counts as late in StreamStats.
inline constexpr int64_t kLateThresholdNs = 1'000'000;

struct StreamCounters {
  StreamStats stats;
  LatenessHistogram lateness;         // since the daemon started
  LatenessHistogram recent_lateness;  // since the last periodic log line
  uint64_t skipped_packets = 0;       // overdue by more than a frame: not sent (see StreamSession)
  uint64_t imu_skipped = 0;

  void record_lidar_send(int64_t lateness_ns) {
    ++stats.lidar_packets_sent;
    lateness.add(lateness_ns);
    recent_lateness.add(lateness_ns);
    if (lateness_ns > kLateThresholdNs) ++stats.late_packets;
    stats.max_lateness_us = lateness.max_us();
  }
};

}  // namespace lidartwin::streamer_detail
