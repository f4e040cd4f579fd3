#include "lidartwin/streamer/streamer.h"

#include <algorithm>
#include <chrono>
#include <fstream>

#include <spdlog/spdlog.h>

#include "lidartwin/log_tag.h"

#include "lidartwin/error.h"
#include "lidartwin/metadata/metadata.h"
#include "streamer/background_jobs.h"
#include "streamer/fault_injector.h"
#include "streamer/ground_truth.h"
#include "streamer/pose_news.h"
#include "streamer/stream_counters.h"
#include "streamer/stream_session.h"
#include "streamer/udp_sender.h"

namespace lidartwin {

using streamer_detail::SessionTiming;
using streamer_detail::steady_now_ns;

namespace {
std::filesystem::path capture_path(const StreamerOptions& options) {
  if (options.record_dir.empty()) return {};
  std::error_code error;
  std::filesystem::create_directories(options.record_dir, error);
  if (error) throw InputError("--record " + options.record_dir.string() + ": cannot create it: " + error.message());
  return options.record_dir / "capture.pcap";
}

// Column timestamps in the config's timestamp_mode (6.3); see the Streamer comment.
int64_t timestamp_offset_ns(const TimeBase& time, const StreamConfig& config) {
  // Validated on the way in (config_rules), so one of the three.
  return time.offset_ns(timestamp_mode_from_string(config.timestamp_mode).value_or(TimestampMode::kInternalOsc));
}

StreamerOptions with_time_base(StreamerOptions options) {
  if (!options.time) options.time = std::make_shared<const TimeBase>(TimeBase::from_host());
  return options;
}

void write_record_metadata(const std::filesystem::path& dir, const StreamConfig& config) {
  if (dir.empty()) return;
  std::ofstream out(dir / "metadata.json");
  out << to_nested_json(config.metadata).dump(2) << "\n";
  if (!out) spdlog::error("streamer: cannot write {}", (dir / "metadata.json").string());
}

std::string describe(const asio::ip::address_v4& address, uint16_t port) {
  return port == 0 ? std::string("off") : address.to_string() + ":" + std::to_string(port);
}

// The first instant of the frame grid (see StreamerOptions) at or after earliest_ns.
int64_t on_frame_grid(int64_t earliest_ns, int64_t origin_ns, int fps) {
  const int64_t period_ns = 1'000'000'000 / std::max(1, fps);
  const int64_t since = earliest_ns - origin_ns;
  const int64_t frames = since <= 0 ? 0 : (since + period_ns - 1) / period_ns;
  return origin_ns + frames * period_ns;
}
}  // namespace

Streamer::Streamer(asio::io_context& io, ModelFactory make_model, StreamerOptions options)
    : io_(io),
      make_model_(std::move(make_model)),
      options_(with_time_base(std::move(options))),
      tag_(log_tag(options_.name)),
      sender_(std::make_unique<streamer_detail::UdpSender>(io, options_.source_address, capture_path(options_))),
      faults_(std::make_unique<streamer_detail::FaultInjector>(io, *sender_, options_.faults,
                                                               [this](SensorFaultEvent event) {
                                                                 if (options_.on_sensor_fault)
                                                                   options_.on_sensor_fault(event);
                                                               })),
      counters_(std::make_unique<streamer_detail::StreamCounters>()),
      ground_truth_(options_.record_dir.empty() ? nullptr
                                                : std::make_unique<streamer_detail::GroundTruth>(options_.record_dir)),
      stats_timer_(io),
      spin_ns_(int64_t{options_.spin_us} * 1000),
      pose_news_(std::make_unique<streamer_detail::PoseNews>()),
      jobs_(std::make_unique<streamer_detail::BackgroundJobs>(options_.render_nice)) {
  if (options_.contention != StreamerOptions::Contention::kAuto) follow_host_load();  // from the first packet
  arm_stats_timer();
}

Streamer::~Streamer() = default;

void Streamer::apply(std::shared_ptr<const StreamConfig> config) {
  asio::post(io_, [this, config = std::move(config)]() mutable { switch_to(std::move(config)); });
}

StreamStats Streamer::stats() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_;
}

void Streamer::switch_to(std::shared_ptr<const StreamConfig> config) {
  if (stopped_ || !config) return;
  if (config_ && config_->generation == config->generation) return;
  stop_session();
  config_ = config;
  if (!config->streaming) {
    spdlog::info("streamer{}: not sending: STANDBY or a sensor fault (config generation {})", tag_, config->generation);
    return;
  }
  if (options_.lock_step) {
    spdlog::info("streamer{}: lock-step: config generation {} starts at the next simulation time", tag_,
                 config->generation);
    return;
  }
  start_paced_session();
}

// On the host's clock, stamped per timestamp_mode, or on the live poses' clock once it is known.
void Streamer::start_paced_session() {
  const int64_t start_steady_ns = on_frame_grid(steady_now_ns() + static_cast<int64_t>(options_.start_delay_s * 1e9),
                                                options_.frame_grid_origin_ns, config_->metadata.format.fps);
  int64_t origin_ns = start_steady_ns + timestamp_offset_ns(*options_.time, *config_);
  if (options_.pose_clock_offset_ns) {
    const std::optional<int64_t> offset = options_.pose_clock_offset_ns();
    if (!offset) {
      spdlog::info("streamer{}: config generation {} starts with the first pose (stamped on the poses' clock)", tag_,
                   config_->generation);
      return;
    }
    origin_ns = start_steady_ns - *offset;
    if (origin_ns < 0) {
      spdlog::error("streamer{}: the poses' clock reads {} ns, before zero: packets cannot carry it", tag_, origin_ns);
      return;
    }
  }
  try {
    start_session(config_, start_steady_ns, static_cast<uint64_t>(origin_ns));
  } catch (const std::exception& e) {
    // The sensor validated the config; a format the packet encoder refuses is reported, and the
    // daemon stays up without streaming until the next reinit.
    spdlog::error("streamer{}: cannot stream config generation {}: {}", tag_, config_->generation, e.what());
  }
}

void Streamer::pose_arrived() {
  pose_news_->arrived();
  if (!options_.pose_clock_offset_ns) return;
  asio::post(io_, [this] {
    if (stopped_ || session_ || building_ || !config_ || !config_->streaming || options_.lock_step) return;
    start_paced_session();
  });
}

void Streamer::advance_to(int64_t time_ns) {
  asio::post(io_, [this, time_ns] {
    if (stopped_ || !config_ || !config_->streaming || time_ns < 0) return;
    const auto time = static_cast<uint64_t>(time_ns);
    if (lock_step_time_ns_ && time <= *lock_step_time_ns_) return;
    lock_step_time_ns_ = time;
    if (!session_) {
      // The simulation's clock stands in for the host's: the session's frame 0 starts now, and its
      // timestamps and pose times are simulation time. Built here: the simulator waits for it.
      try {
        land_session(build_session(config_, time_ns, time), config_);
      } catch (const std::exception& e) {
        spdlog::error("streamer{}: cannot stream config generation {}: {}", tag_, config_->generation, e.what());
        return;
      }
    }
    session_->advance_to(time);
  });
}

// Paced sessions are built off the io thread (background_jobs.h) and start sending when they land
// back on it; frame 0 is start_delay_s away, time enough. The io_context is kept busy meanwhile,
// so that run() cannot return with a session still in the making.
void Streamer::start_session(std::shared_ptr<const StreamConfig> config, int64_t start_steady_ns, uint64_t origin_ns) {
  const uint64_t ticket = ++session_ticket_;
  building_ = true;
  jobs_->post([this, config = std::move(config), start_steady_ns, origin_ns, ticket,
               busy = asio::make_work_guard(io_)]() mutable {
    std::shared_ptr<streamer_detail::StreamSession> session;
    try {
      session = build_session(config, start_steady_ns, origin_ns);
    } catch (const std::exception& e) {
      // The sensor validated the config; a format the packet encoder refuses is reported, and the
      // daemon stays up without streaming until the next reinit.
      spdlog::error("streamer{}: cannot stream config generation {}: {}", tag_, config->generation, e.what());
    }
    asio::post(io_, [this, session = std::move(session), config = std::move(config), ticket]() mutable {
      if (stopped_ || ticket != session_ticket_) {
        if (session) retire(std::move(session));  // a newer config or stop() came meanwhile
        return;
      }
      building_ = false;
      if (session) land_session(std::move(session), config);
    });
    busy.reset();
  });
}

// Any thread: the model, its render worker (which starts casting) and the buffers.
std::shared_ptr<streamer_detail::StreamSession> Streamer::build_session(
    const std::shared_ptr<const StreamConfig>& config, int64_t start_steady_ns, uint64_t origin_ns) {
  const LidarDataFormat& format = config->metadata.format;
  const UdpProfileImu imu_profile = format.udp_profile_imu;
  const bool imu = config->udp_port_imu != 0 && imu_profile == UdpProfileImu::kLegacy;
  if (config->udp_port_imu != 0 && imu_profile == UdpProfileImu::kAccel32Gyro32Nmea) {
    spdlog::warn("streamer{}: udp_profile_imu ACCEL32_GYRO32_NMEA is not emulated; no IMU packets are sent", tag_);
  }
  SessionTiming timing;
  timing.start_steady_ns = start_steady_ns;
  std::unique_ptr<ForwardModel> model = make_model_(*config, start_steady_ns, origin_ns);
  timing.clock = model->clock();
  spdlog::info("streamer{}: lidar {} {} ({} packets of {} B per frame) from {}:{} to {}, init_id {}", tag_,
               to_string(LidarMode{format.columns_per_frame, format.fps}), to_string(format.udp_profile_lidar),
               model->packet_columns().size(), model->packet_size(),
               asio::ip::address_v4(options_.source_address).to_string(), sender_->source_port(),
               describe(asio::ip::address_v4(config->udp_dest), config->udp_port_lidar), config->init_id);
  spdlog::info("streamer{}: IMU to {}", tag_,
               describe(asio::ip::address_v4(config->udp_dest), imu ? config->udp_port_imu : 0));
  write_record_metadata(options_.record_dir, *config);
  streamer_detail::StreamSession::Options session_options;
  session_options.send_imu = imu;
  session_options.frames_ahead = options_.frames_ahead;
  session_options.render_nice = options_.render_nice;
  session_options.spin_ns = &spin_ns_;
  if (options_.cast_ahead_ms <= 0.0) session_options.coalesce_ns = &coalesce_ns_;
  session_options.cast_ahead_ns = static_cast<int64_t>(options_.cast_ahead_ms * 1e6);
  session_options.pose_news = pose_news_.get();
  session_options.withhold_unposed = options_.withhold_unposed;
  session_options.lock_step = options_.lock_step;
  return std::make_shared<streamer_detail::StreamSession>(io_, *faults_, *counters_, ground_truth_.get(), config,
                                                          std::move(model), timing, session_options);
}

// Io thread: the session starts sending.
void Streamer::land_session(std::shared_ptr<streamer_detail::StreamSession> session,
                            const std::shared_ptr<const StreamConfig>& config) {
  const bool lidar = config->udp_port_lidar != 0;
  const std::optional<PacketFormat> packets =
      lidar ? std::optional<PacketFormat>(config->metadata.format) : std::nullopt;
  faults_->start_session(*config, packets ? &*packets : nullptr, config->metadata.format.fps);
  session_ = std::move(session);
  session_->start();
}

void Streamer::stop_session() {
  ++session_ticket_;  // a session still being built is retired when it lands
  building_ = false;
  if (!session_) return;
  session_->stop();
  retire(std::move(session_));
  faults_->end_session();
}

// Io thread, after session->stop(): its worker is joined and its memory freed off the io thread.
void Streamer::retire(std::shared_ptr<streamer_detail::StreamSession> session) {
  session->stop();
  jobs_->post([session = std::move(session)] { session->release(); });
}

void Streamer::stop() {
  if (stopped_) return;
  stopped_ = true;
  stop_session();
  stats_timer_.cancel();
  sender_->close();
  if (ground_truth_) ground_truth_->close();
  const auto& stats = counters_->stats;
  spdlog::info(
      "streamer{}: stopped after {} lidar packets ({} frames) and {} IMU packets; send lateness {}; "
      "{} render stalls, {} skipped",
      tag_, stats.lidar_packets_sent, stats.frames_sent, stats.imu_packets_sent, counters_->lateness.summary(),
      stats.render_stalls, counters_->skipped_packets);
}

}  // namespace lidartwin
