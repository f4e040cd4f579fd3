// The Streamer's once-a-second report: StreamStats to the sensor, and warnings when casting or
// the host cannot keep up (rate-limited: one line per kWarningInterval at most).
#include <spdlog/spdlog.h>

#include "lidartwin/streamer/coalescing_window.h"
#include "lidartwin/streamer/streamer.h"
#include "streamer/host_load.h"
#include "streamer/stream_counters.h"
#include "streamer/stream_session.h"
#include "streamer/udp_sender.h"

namespace lidartwin {

using streamer_detail::steady_now_ns;

namespace {
constexpr int64_t kStatsPeriodNs = 1'000'000'000;
constexpr int64_t kWarningIntervalNs = 5'000'000'000;
constexpr uint64_t kDebugLogTicks = 10;
}  // namespace

void Streamer::arm_stats_timer() {
  next_stats_ns_ = (next_stats_ns_ == 0 ? steady_now_ns() : next_stats_ns_) + kStatsPeriodNs;
  stats_timer_.expires_at(asio::steady_timer::time_point(std::chrono::nanoseconds(next_stats_ns_)));
  stats_timer_.async_wait([this](const asio::error_code& error) {
    if (error || stopped_) return;
    report_stats();
    arm_stats_timer();
  });
}

void Streamer::report_stats() {
  follow_host_load();
  StreamStats& stats = counters_->stats;
  stats.coalesce_window_us = static_cast<double>(coalesce_ns_) / 1000.0;
  const uint64_t busy_ns = session_ ? session_->take_render_busy_ns() : 0;
  stats.columns_without_pose += session_ ? session_->take_unposed_columns() : 0;
  stats.recast_packets += session_ ? session_->take_recasts() : 0;
  stats.render_load = static_cast<double>(busy_ns) / static_cast<double>(kStatsPeriodNs);
  stats.skipped_packets = counters_->skipped_packets;
  stats.lateness_p50_us = counters_->lateness.percentile_us(0.5);
  stats.lateness_p99_us = counters_->lateness.percentile_us(0.99);
  warn_if_behind(stats.render_load);
  if (++stats_ticks_ % kDebugLogTicks == 0) {
    spdlog::debug("streamer{}: {} lidar, {} IMU packets; recent send lateness {}; render load {:.2f}", tag_,
                  stats.lidar_packets_sent, stats.imu_packets_sent, counters_->recent_lateness.summary(),
                  stats.render_load);
    counters_->recent_lateness = {};
  }
  if (std::unique_lock lock(snapshot_mutex_, std::try_to_lock); lock) snapshot_ = stats;
}

// The send clock spins to each deadline only while the host has CPU to spare. While it has not,
// and casting has fallen behind (a render stall since the last look), the send clock coalesces
// its wake-ups, trading punctuality for the CPU casting lacks (coalescing_window.h: the window
// widens while casting still falls behind), until the host is free again (a rig of 16 on a
// contended host that keeps up stays punctual).
void Streamer::follow_host_load() {
  using Contention = StreamerOptions::Contention;
  const uint64_t stalls = counters_->stats.render_stalls;
  const bool stalled = stalls > stalls_at_last_look_;
  stalls_at_last_look_ = stalls;
  if (options_.contention == Contention::kAuto && options_.spin_us <= 0 && options_.coalesce_us <= 0) return;
  const bool contended = options_.contention == Contention::kAuto ? streamer_detail::host_contended()
                                                                  : options_.contention == Contention::kAlways;
  spin_ns_ = contended ? 0 : int64_t{options_.spin_us} * 1000;
  const bool coalesce = contended && (coalesce_ns_ > 0 || stalled || options_.contention == Contention::kAlways);
  const int64_t window = next_coalescing_window(coalesce_ns_, int64_t{options_.coalesce_us} * 1000, coalesce, stalled);
  if (window > 0 && coalesce_ns_ == 0) {
    spdlog::info(
        "streamer{}: {}: the send clock wakes once for the packets due within {} us of each other (--coalesce-us), "
        "holding the earlier ones back",
        tag_, stalled ? "casting fell behind on a contended host" : "--contention always", options_.coalesce_us);
  } else if (window > coalesce_ns_ && coalesce_ns_ > 0) {
    spdlog::debug("streamer{}: casting still falls behind: the send clock wakes once for the packets due within {} us",
                  tag_, window / 1000);
  }
  coalesce_ns_ = window;
}

void Streamer::warn_if_behind(double render_load) {
  const StreamStats& stats = counters_->stats;
  const uint64_t skipped = counters_->skipped_packets + counters_->imu_skipped;
  const bool news = stats.render_stalls > warned_stalls_ || skipped > warned_skips_ ||
                    stats.late_packets > warned_late_ || sender_->errors() > warned_errors_ ||
                    stats.columns_without_pose > warned_unposed_ || stats.withheld_packets > warned_withheld_;
  const int64_t now = steady_now_ns();
  if (!news || now - last_warning_ns_ < kWarningIntervalNs) return;
  if (stats.render_stalls > warned_stalls_) {
    spdlog::warn(
        "streamer{}: casting is behind the send clock: {} packets sent on time with their columns marked "
        "invalid ({} in total; render load {:.2f}; try fewer --threads elsewhere, a smaller scene or mode)",
        tag_, stats.render_stalls - warned_stalls_, stats.render_stalls, render_load);
  }
  if (stats.late_packets > warned_late_) {
    spdlog::warn(
        "streamer{}: {} packets sent more than 1 ms late ({} in total; send lateness p99 {:.0f} us, max {:.0f} "
        "us): the host kept the send clock from running",
        tag_, stats.late_packets - warned_late_, stats.late_packets, stats.lateness_p99_us, stats.max_lateness_us);
  }
  if (skipped > warned_skips_) {
    spdlog::warn("streamer{}: the host stalled the send clock for more than a frame: {} packets skipped ({} in total)",
                 tag_, skipped - warned_skips_, skipped);
  }
  if (sender_->errors() > warned_errors_) {
    spdlog::warn("streamer{}: {} UDP sends failed ({} in total; the last: {}); streaming goes on", tag_,
                 sender_->errors() - warned_errors_, sender_->errors(), sender_->last_error());
  }
  if (stats.columns_without_pose > warned_unposed_ || stats.withheld_packets > warned_withheld_) {
    spdlog::warn(
        "streamer{}: {} columns had no pose ({} in total; {}), {} packets withheld ({} in total): the live "
        "pose stream is late or stalled (GET /lidartwin/v1/pose)",
        tag_, stats.columns_without_pose - warned_unposed_, stats.columns_without_pose,
        options_.withhold_unposed ? "not sent" : "sent with status 0", stats.withheld_packets - warned_withheld_,
        stats.withheld_packets);
  }
  warned_unposed_ = stats.columns_without_pose;
  warned_withheld_ = stats.withheld_packets;
  warned_stalls_ = stats.render_stalls;
  warned_late_ = stats.late_packets;
  warned_skips_ = skipped;
  warned_errors_ = sender_->errors();
  last_warning_ns_ = now;
}

}  // namespace lidartwin
