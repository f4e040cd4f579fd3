#pragma once
// What the send clock counts, on the io thread only; the Streamer reports it once a second.
#include <cstdint>

#include "lidartwin/pose/pose_source.h"
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
  LatenessHistogram pose_latency;   // a pose's arrival -> the first packet cast with it was sent
  uint64_t pose_revision_sent = 0;  // the newest pose revision a sent packet was cast with

  // A packet cast with poses up to `freshness` was sent at now_ns.
  void record_pose_use(const PoseFreshness& freshness, int64_t now_ns) {
    if (freshness.revision <= pose_revision_sent) return;
    pose_revision_sent = freshness.revision;
    pose_latency.add(now_ns - freshness.arrival_steady_ns);
    stats.pose_latency_count = pose_latency.count();
    stats.pose_latency_p50_us = pose_latency.percentile_us(0.5);
    stats.pose_latency_p99_us = pose_latency.percentile_us(0.99);
    stats.pose_latency_max_us = pose_latency.max_us();
  }

  // held_ns: how long the send clock meant to hold packets back (coalesced wake-ups); later than
  // that by the threshold is late.
  void record_lidar_send(int64_t lateness_ns, int64_t held_ns) {
    ++stats.lidar_packets_sent;
    lateness.add(lateness_ns);
    recent_lateness.add(lateness_ns);
    if (lateness_ns > kLateThresholdNs + held_ns) ++stats.late_packets;
    stats.max_lateness_us = lateness.max_us();
  }
};

}  // namespace lidartwin::streamer_detail
