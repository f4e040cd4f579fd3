#pragma once
// The daemon's UDP side: paces and sends what the forward model makes, lidar packets on the column
// clock and IMU packets at 100 Hz, to whatever the active StreamConfig says (protocol doc 1 items
// 8-13, 5.1, 6). Casting runs ahead of the send clock on a worker. One Streamer per virtual sensor;
// it runs on the caller's io_context.
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>

#include <asio.hpp>

#include "lidartwin/fault/fault_control.h"
#include "lidartwin/frame/forward_model.h"
#include "lidartwin/sensor/stream_config.h"
#include "lidartwin/sensor/time_base.h"

namespace lidartwin {

namespace streamer_detail {
class UdpSender;
class StreamSession;
struct StreamCounters;
class GroundTruth;
class FaultInjector;
class BackgroundJobs;
class PoseNews;
}  // namespace streamer_detail

// The sensor's own faults a FaultPlan schedules (reset_at, standby_at, error_at): the streamer
// stops the session at the frame where one is due and hands it to whoever owns the sensor.
enum class SensorFaultEvent { kReset, kStandby, kError };

struct StreamerOptions {
  std::array<uint8_t, 4> source_address{127, 0, 0, 1};  // the sensor's own address (item 8)
  // A rig's sensor name: its log lines read "streamer (roof): ..." (empty: a lone sensor's).
  std::string name;
  // The clocks packets are stamped on, per timestamp_mode: the sensor's own (Sensor::time()), which
  // its HTTP API reports too. Null: a time base of the streamer's own.
  std::shared_ptr<const TimeBase> time = nullptr;
  // Non-empty: capture.pcap + metadata.json of what is sent, and its ground truth poses.tum and
  // column_poses.tum (as `record` writes them).
  std::filesystem::path record_dir;
  int frames_ahead = 2;         // how far casting may run ahead of the send clock
  double start_delay_s = 0.25;  // from a reinit to frame 0 (at least): time to cast the first packets
  // Frame 0 starts on this grid: at frame_grid_origin_ns + k / fps on the host's steady clock, the
  // first such instant start_delay_s after the reinit. A rig gives its sensors one origin, so that
  // the packets of sensors in one mode fall due at the same instants and one wake-up of the rig's
  // send clock sends them all (a wake-up costs far more CPU than a send, most of all on a VM).
  int64_t frame_grid_origin_ns = 0;
  int render_nice = 0;  // nice value of the render-ahead worker (the send clock keeps 0)
  // The send clock wakes this early and spins to each lidar deadline: a thread's wake-up takes
  // 50-100 us on a VM. Costs about spin_us x packets/s of CPU at most (10 % at 2048x10), so it
  // spins only while the host's CPUs are not contended (streamer/host_load.h): on a full host the
  // spin would be taken from rendering, its own or other daemons'.
  int spin_us = 100;
  // While the host is contended and casting has fallen behind, the send clock wakes once for the
  // packets due within this much of each other, holding the earlier ones back (never sending one
  // before its time), and sends the IMU samples due by then with them: one wake-up serves two
  // packets of a 1024x10 stream, and a wake-up costs ~100 us of CPU on a VM (a dozen daemons'
  // send clocks on one host would take the CPU their casting needs). While casting still falls
  // behind, the window doubles once a second up to 8 times this (20 ms at most), and halves back
  // once it keeps up. 0: one wake-up per packet always. Not with cast_ahead_ms, whose packets wait
  // for the freshest pose.
  int coalesce_us = 2000;
  // Whether the host counts as contended (no spin, coalesced sends): kAuto follows the host's CPU
  // pressure (streamer/host_load.h); a user who knows better (a CPU quota PSI does not show, a
  // test) says so.
  enum class Contention { kAuto, kAlways, kNever };
  Contention contention = Contention::kAuto;
  // Live poses (docs/live-poses.md): > 0 casts each packet first this long before it is due, and
  // again if a pose arrives before it is due (frames_ahead still bounds the buffers); 0 casts as
  // far ahead as it can.
  double cast_ahead_ms = 0.0;
  bool withhold_unposed = false;  // timeout policy "standby": packets with no posed column are not sent
  // The simulator owns time (docs/live-poses.md, "Lock-step"): nothing is sent on the host's clock;
  // advance_to(t) sends every packet stamped up to t. A config's frame 0 starts at the first t
  // after it became active, and every timestamp (whatever timestamp_mode says) is on that clock.
  bool lock_step = false;
  // Set: paced on the host's clock but stamped on the live poses' clock (a simulator's time):
  // timestamp = host steady clock - this offset. A config waits for the first pose (nullopt until
  // then); pose_arrived() says when to look again.
  std::function<std::optional<int64_t>()> pose_clock_offset_ns;
  // Faults injected into what is sent (docs/fault-injection.md); null: none. Must outlive the
  // streamer. on_sensor_fault runs on the io thread when the plan's sensor event is due.
  FaultControl* faults = nullptr;
  std::function<void(SensorFaultEvent)> on_sensor_fault;
};

// The forward model of a config (its beams, format, signal_multiplier, init_id, prod_sn) whose
// frame 0 is observed at start_steady_ns on the host's steady clock, its column 0 stamped origin_ns.
// Throws InputError naming a format the packet encoder cannot carry.
using ModelFactory = std::function<std::unique_ptr<ForwardModel>(const StreamConfig& config, int64_t start_steady_ns,
                                                                 uint64_t origin_ns)>;

// Column and IMU timestamps (6.3) are the time base's (sensor/time_base.h): TIME_FROM_INTERNAL_OSC
// and TIME_FROM_SYNC_PULSE_IN carry the host's CLOCK_MONOTONIC in ns, so the timestamp of a
// packet's last column is exactly the steady-clock instant it was due: a receiver on the same
// host measures send lateness as (receive CLOCK_MONOTONIC - that timestamp). TIME_FROM_PTP_1588
// carries TAI ns, the same instant plus the time base's fixed offset.
//
// Lateness is also logged: a debug line every 10 s and an info line at stop(), "lateness p50 .. us,
// p99 .. us, max .. us", and a warning (at most one per 5 s) when packets went out more than 1 ms
// late, had to go out unrendered (render stalls) or were skipped; StreamStats carries the counts,
// the lateness percentiles and render_load, per sensor (a rig's streamers each their own).
// lidar_frame_azimuth_offset reaches the packets through the served beam intrinsics (the model
// casts with them); frames always start at m = 0. Not handled: IMU profiles other than LEGACY (a
// warning; no IMU packets are sent).
class Streamer {
 public:
  // Throws InputError if the sending socket cannot be bound or the record directory cannot be
  // written.
  Streamer(asio::io_context& io, ModelFactory make_model, StreamerOptions options);
  ~Streamer();
  Streamer(const Streamer&) = delete;
  Streamer& operator=(const Streamer&) = delete;

  // Any thread. A config with a new generation restarts the stream (new format, init_id and
  // frame_id sequence); streaming=false (STANDBY) stops it; port 0 turns that stream off.
  void apply(std::shared_ptr<const StreamConfig> config);
  // Any thread. Lock-step only: the simulation's time is now time_ns.
  void advance_to(int64_t time_ns);
  // Any thread: a live pose arrived. The render worker casts again, with it, the packets it cast
  // before it that are not yet due; with pose_clock_offset_ns, a waiting config may start.
  void pose_arrived();
  // Any thread: the stats as of the last once-a-second update. The send clock never waits for a
  // reader (it skips an update rather than block), so a reader may be up to a second behind.
  StreamStats stats() const;
  // Io thread (or before run): cancels the clocks, joins the render worker, closes the socket,
  // so that io_context::run() can return.
  void stop();

 private:
  void switch_to(std::shared_ptr<const StreamConfig> config);
  void start_session(std::shared_ptr<const StreamConfig> config, int64_t start_steady_ns, uint64_t origin_ns);
  std::shared_ptr<streamer_detail::StreamSession> build_session(const std::shared_ptr<const StreamConfig>& config,
                                                                int64_t start_steady_ns, uint64_t origin_ns);
  void land_session(std::shared_ptr<streamer_detail::StreamSession> session,
                    const std::shared_ptr<const StreamConfig>& config);
  void start_paced_session();
  void stop_session();
  void retire(std::shared_ptr<streamer_detail::StreamSession> session);
  void arm_stats_timer();
  void report_stats();
  void warn_if_behind(double render_load);
  void follow_host_load();

  asio::io_context& io_;
  ModelFactory make_model_;
  StreamerOptions options_;
  std::string tag_;  // " (roof)" after "streamer" in log lines, for a rig's sensor
  std::unique_ptr<streamer_detail::UdpSender> sender_;
  std::unique_ptr<streamer_detail::FaultInjector> faults_;  // between the sessions and sender_
  std::unique_ptr<streamer_detail::StreamCounters> counters_;
  std::unique_ptr<streamer_detail::GroundTruth> ground_truth_;  // with record_dir
  asio::steady_timer stats_timer_;
  int64_t spin_ns_;          // options_.spin_us, or 0 while the host is contended; io thread
  int64_t coalesce_ns_ = 0;  // the coalescing window (follow_host_load), 0 when not coalescing; io thread
  uint64_t stalls_at_last_look_ = 0;
  mutable std::mutex snapshot_mutex_;
  StreamStats snapshot_;                                     // guarded by snapshot_mutex_
  std::shared_ptr<const StreamConfig> config_;               // the one being streamed
  std::shared_ptr<streamer_detail::StreamSession> session_;  // null in STANDBY or when stopped
  uint64_t session_ticket_ = 0;                // the session being built, if building; a newer one cancels it
  bool building_ = false;                      // a session is being built off the io thread
  std::optional<uint64_t> lock_step_time_ns_;  // the newest simulation time, in lock-step
  int64_t next_stats_ns_ = 0;                  // steady clock
  uint64_t stats_ticks_ = 0;
  uint64_t warned_stalls_ = 0;
  uint64_t warned_late_ = 0;
  uint64_t warned_skips_ = 0;
  uint64_t warned_errors_ = 0;
  uint64_t warned_unposed_ = 0;
  uint64_t warned_withheld_ = 0;
  int64_t last_warning_ns_ = 0;
  bool stopped_ = false;
  std::unique_ptr<streamer_detail::PoseNews> pose_news_;  // read by the sessions' render workers
  // Last: sessions it builds or retires are done with before the members above go.
  std::unique_ptr<streamer_detail::BackgroundJobs> jobs_;
};

}  // namespace lidartwin
