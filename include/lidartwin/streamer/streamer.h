#pragma once
// The daemon's UDP side: renders the scene ahead of time and sends lidar packets on the column
// clock and IMU packets at 100 Hz, to whatever the active StreamConfig says (protocol doc 1 items
// 8-13, 5.1, 6). One Streamer per virtual sensor; it runs on the caller's io_context.
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>

#include <asio.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/render/frame_renderer.h"
#include "lidartwin/scene/scene.h"
#include "lidartwin/sensor/stream_config.h"

namespace lidartwin {

namespace streamer_detail {
class UdpSender;
class StreamSession;
class RenderAhead;
struct SessionTiming;
struct StreamCounters;
}  // namespace streamer_detail

struct StreamerOptions {
  std::array<uint8_t, 4> source_address{127, 0, 0, 1};  // the sensor's own address (item 8)
  RenderConfig render;                 // seed and threads; signal_gain comes from each config
  std::filesystem::path record_dir;    // non-empty: capture.pcap + metadata.json of what is sent
  int frames_ahead = 2;                // how far casting may run ahead of the send clock
  double start_delay_s = 0.25;         // from a reinit to frame 0: time to cast the first packets
  int render_nice = 0;                 // nice value of the casting threads (the send clock keeps 0)
  // The send clock wakes this early and spins to each lidar deadline: a thread's wake-up takes
  // 50-100 us on a VM. Costs about spin_us x packets/s of CPU at most (10 % at 2048x10).
  int spin_us = 100;
};

// Column timestamps (6.3): TIME_FROM_INTERNAL_OSC and TIME_FROM_SYNC_PULSE_IN carry the host's
// CLOCK_MONOTONIC in ns (time since boot, as a real sensor's oscillator counts), so the timestamp
// of a packet's last column is exactly the steady-clock instant it was due: a receiver on the same
// host measures send lateness as (receive CLOCK_MONOTONIC - that timestamp). TIME_FROM_PTP_1588
// carries TAI ns (CLOCK_REALTIME + 37 s).
//
// Lateness is also logged: a debug line every 10 s and an info line at stop(), "lateness p50 .. us,
// p99 .. us, max .. us"; StreamStats carries late_packets, max_lateness_us, render_stalls and
// render_load. Not handled: lidar_frame_azimuth_offset (frames always start at m = 0), and IMU
// profiles other than LEGACY (a warning; no IMU packets are sent).
class Streamer {
 public:
  // scene must outlive the Streamer. Throws InputError if the sending socket cannot be bound or
  // the record directory cannot be written.
  Streamer(asio::io_context& io, const Scene& scene, SensorProfile profile, EffectChain chain, Trajectory trajectory,
           StreamerOptions options);
  ~Streamer();
  Streamer(const Streamer&) = delete;
  Streamer& operator=(const Streamer&) = delete;

  // Any thread. A config with a new generation restarts the stream (new format, init_id and
  // frame_id sequence); streaming=false (STANDBY) stops it; port 0 turns that stream off.
  void apply(std::shared_ptr<const StreamConfig> config);
  // Any thread: the stats as of the last once-a-second update. The send clock never waits for a
  // reader (it skips an update rather than block), so a reader may be up to a second behind.
  StreamStats stats() const;
  // Io thread (or before run): cancels the clocks, joins the render worker, closes the socket,
  // so that io_context::run() can return.
  void stop();

 private:
  void switch_to(std::shared_ptr<const StreamConfig> config);
  void start_session(std::shared_ptr<const StreamConfig> config);
  streamer_detail::SessionTiming session_timing(const StreamConfig& config) const;
  std::unique_ptr<streamer_detail::RenderAhead> start_rendering(std::shared_ptr<const StreamConfig> config,
                                                                const streamer_detail::SessionTiming& timing);
  void stop_session();
  void arm_stats_timer();
  void report_stats();
  void warn_if_behind(double render_load);

  asio::io_context& io_;
  const Scene& scene_;
  SensorProfile profile_;
  EffectChain chain_;
  Trajectory trajectory_;
  StreamerOptions options_;
  int64_t daemon_start_ns_ = 0;  // trajectory time 0
  std::unique_ptr<streamer_detail::UdpSender> sender_;
  std::unique_ptr<streamer_detail::StreamCounters> counters_;
  asio::steady_timer stats_timer_;
  mutable std::mutex snapshot_mutex_;
  StreamStats snapshot_;  // guarded by snapshot_mutex_
  std::shared_ptr<const StreamConfig> config_;                // the one being streamed
  std::shared_ptr<streamer_detail::StreamSession> session_;   // null in STANDBY or when stopped
  int64_t next_stats_ns_ = 0;  // steady clock
  uint64_t stats_ticks_ = 0;
  uint64_t warned_stalls_ = 0;
  uint64_t warned_skips_ = 0;
  uint64_t warned_errors_ = 0;
  int64_t last_warning_ns_ = 0;
  bool stopped_ = false;
};

}  // namespace lidartwin
