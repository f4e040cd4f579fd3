#include "lidartwin/rig/virtual_sensor.h"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <mutex>

#include <spdlog/spdlog.h>

#include "lidartwin/frame/forward_model.h"
#include "lidartwin/json/json_reader.h"
#include "lidartwin/log_tag.h"
#include "lidartwin/rig/fault_api.h"
#include "lidartwin/rig/pose_api.h"

namespace lidartwin {

namespace {
HttpServerOptions with_extensions(HttpServerOptions http, VirtualSensor& sensor, FaultControl& faults) {
  http.lidartwin_api = [&sensor](const ApiRequest& request) { return sensor.lidartwin_endpoint(request); };
  http.faults = &faults;
  return http;
}
// A rig's sensor name, for the server's and the streamer's log lines.
template <typename Options>
Options named(Options options, const std::string& name) {
  options.name = name;
  return options;
}
StreamerOptions with_faults(StreamerOptions options, VirtualSensor& sensor, FaultControl& faults) {
  options.faults = &faults;
  options.on_sensor_fault = [&sensor](SensorFaultEvent event) { sensor.on_sensor_fault(event); };
  return options;
}
// One time base for the sensor and its streamer (and, through the rig, for every sensor).
RigContext with_time_base(RigContext rig) {
  if (!rig.time) rig.time = std::make_shared<const TimeBase>(TimeBase::from_host());
  return rig;
}
SensorOptions with_time(SensorOptions options, const RigContext& rig, VirtualSensor& sensor, bool lock_step,
                        bool stamp_pose_clock) {
  options.time = rig.time;
  if (rig.waiting_motion) options.on_client = [&sensor](ClientEvent event) { sensor.on_client(event); };
  // The packets' clock, when it is the poses': in lock-step the simulation's time is the newest
  // pose's (packets go out up to it); stamped on the poses' clock, it runs on from the newest pose.
  LivePoses* live = rig.live;
  if (live && lock_step) {
    options.packets_clock_ns = [live]() -> std::optional<int64_t> {
      const LivePoseStats stats = live->stats();
      if (!stats.newest) return std::nullopt;
      return stats.newest->time_ns;
    };
  } else if (live && stamp_pose_clock) {
    options.packets_clock_ns = [live]() -> std::optional<int64_t> {
      const LivePoseStats stats = live->stats();
      if (!stats.newest) return std::nullopt;
      return TimeBase::steady_now_ns() - stats.clock_offset_ns;
    };
  }
  return options;
}
StreamerOptions with_time(StreamerOptions options, const RigContext& rig) {
  options.time = rig.time;
  options.frame_grid_origin_ns = rig.epoch_steady_ns;  // the rig's sensors' frames start together
  return options;
}
// The live poses' clock offset (host steady - pose clock) once a pose has come.
StreamerOptions with_pose_clock(StreamerOptions options, LivePoses* live, bool stamp_pose_clock) {
  if (!live || !stamp_pose_clock) return options;
  options.pose_clock_offset_ns = [live]() -> std::optional<int64_t> {
    const LivePoseStats stats = live->stats();
    if (!stats.newest) return std::nullopt;
    return stats.clock_offset_ns;
  };
  return options;
}
}  // namespace

VirtualSensor::VirtualSensor(const RigContext& rig, VirtualSensorSetup setup)
    : rig_(with_time_base(rig)),
      log_tag_(log_tag(setup.name)),
      poses_(rig.poses, setup.mounting),
      per_column_poses_(setup.per_column_poses),
      lock_step_(setup.streamer.lock_step),
      imu_noise_(setup.imu_noise),
      stamp_pose_clock_(setup.stamp_pose_clock && rig.live != nullptr),
      max_range_m_(setup.max_range_m),
      chain_(std::move(setup.chain)),
      seed_(setup.seed),
      frames_ahead_(setup.streamer.frames_ahead),
      faults_(std::move(setup.faults), setup.name),
      fault_timer_(rig.io),
      sensor_(std::move(setup.identity),
              with_time(std::move(setup.sensor), rig_, *this, setup.streamer.lock_step, setup.stamp_pose_clock)),
      http_(sensor_, with_extensions(named(std::move(setup.http), setup.name), *this, faults_)),
      streamer_(
          rig.io,
          [this](const StreamConfig& config, int64_t start_steady_ns, uint64_t origin_ns) {
            return make_model(config, start_steady_ns, origin_ns);
          },
          with_faults(with_pose_clock(with_time(named(std::move(setup.streamer), setup.name), rig_), rig.live,
                                      setup.stamp_pose_clock),
                      *this, faults_)) {}

// lidartwin's own endpoints: faults always, live poses when they arrive live.
ApiResponse VirtualSensor::lidartwin_endpoint(const ApiRequest& request) {
  const std::string path = origin_form_path(request.path);
  std::string_view resource(path);
  resource.remove_prefix(kExtensionPrefix.size());
  while (resource.ends_with('/')) resource.remove_suffix(1);
  if (resource == "faults") return fault_endpoint(faults_, seed_, request);
  if (resource == "pose" && rig_.live) return live_pose_endpoint(*rig_.live, streamer_.stats(), request);
  throw HttpError(404, "unknown endpoint " + path + ": lidartwin answers /lidartwin/v1/faults" +
                           (rig_.live ? " and /lidartwin/v1/pose" : " (and /lidartwin/v1/pose with live poses)"));
}

// On the io thread, where the streamer stopped the session at the frame the plan named.
void VirtualSensor::on_sensor_fault(SensorFaultEvent event) {
  const FaultPlan plan = faults_.plan();
  if (event == SensorFaultEvent::kReset) {
    sensor_.restart();
    return;
  }
  const bool error = event == SensorFaultEvent::kError;
  std::optional<SensorAlert> alert;
  if (error) {
    alert = SensorAlert{"0x01000015", "OVERTEMP", "ERROR", "Sensor overheating; the sensor stopped.",
                        "Injected by lidartwin's fault plan (error_at): the sensor stays in ERROR for " +
                            json_reader::format_number(plan.error_for) + " s, then restarts."};
  }
  sensor_.enter_fault_state(error ? "ERROR" : "STANDBY", alert);
  fault_timer_.expires_after(
      std::chrono::nanoseconds(static_cast<int64_t>((error ? plan.error_for : plan.standby_for) * 1e9)));
  fault_timer_.async_wait([this](const asio::error_code& failed) {
    if (failed) return;
    sensor_.leave_fault_state();
    faults_.record("recovered", {{"init_id", sensor_.stream_config()->init_id}});
  });
}

VirtualSensor::~VirtualSensor() {
  stop();
  stop_streaming();  // a no-op when the rig stopped it on the io thread
}

// The model of the config as served: its beams (lidar_frame_azimuth_offset rotates them), format,
// signal_multiplier and identity; the profile's physics; the rig's motion on the rig's time.
std::unique_ptr<ForwardModel> VirtualSensor::make_model(const StreamConfig& config, int64_t start_steady_ns,
                                                        uint64_t origin_ns) {
  const LidarDataFormat& format = config.metadata.format;
  ForwardModelSetup setup;
  setup.render = {config.metadata.beams, format, max_range_m_, chain_, seed_, config.signal_multiplier};
  setup.origin_ns = origin_ns;
  setup.pose_origin_s = rig_time_s(start_steady_ns);
  setup.init_id = config.init_id;
  setup.prod_sn = config.prod_sn;
  setup.per_column_poses = per_column_poses_;
  setup.imu_noise = imu_noise_;
  on_session(setup.pose_origin_s, format.fps);
  return std::make_unique<ForwardModel>(rig_.scene, poses_, std::move(setup), rig_.pool);
}

// The pose source's time at a steady-clock instant.
double VirtualSensor::rig_time_s(int64_t steady_ns) const {
  return rig_.poses.start_s() + static_cast<double>(steady_ns - rig_.epoch_steady_ns) * 1e-9;
}

// A session begins (io thread, before it casts anything): a motion a client's reinit asked for
// starts with its frame 0, so the stream the client configured shows the trajectory from its start.
void VirtualSensor::on_session(double pose_origin_s, int fps) {
  {
    std::lock_guard lock(session_mutex_);
    session_frames_ = SessionFrames{pose_origin_s, fps};
  }
  if (!rig_.waiting_motion || !start_motion_with_session_.exchange(false)) return;
  if (rig_.waiting_motion->start_at(pose_origin_s)) {
    spdlog::info("serve{}: a client configured {}: the motion starts with frame 0 of its stream (pose time {:.3f} s)",
                 log_tag_, sensor_.identity().prod_sn, pose_origin_s);
  }
}

// serve --motion-start configured. A reinit starts the motion with the session it starts (above).
// A client that never reinitializes (SDK 1.0's SensorPacketSource when the config already suits
// it) reads the metadata before it streams: the motion then starts at the first frame of the
// running session that the streamer cannot have cast yet (it casts frames_ahead frames beyond the
// one being sent), so every packet and the ground truth show the pose it was cast from.
void VirtualSensor::on_client(ClientEvent event) {
  if (!rig_.waiting_motion || rig_.waiting_motion->started_at()) return;
  if (event == ClientEvent::kReinit) {
    start_motion_with_session_ = true;
    return;
  }
  if (start_motion_with_session_) return;  // a reinit's session starts it
  std::lock_guard lock(session_mutex_);
  if (!session_frames_) {
    start_motion_with_session_ = true;  // not streaming yet: with the first session
    return;
  }
  const auto [origin_s, fps] = *session_frames_;
  const double earliest_s = rig_time_s(TimeBase::steady_now_ns()) + (frames_ahead_ + 1.0) / fps;
  const double frame = std::max(std::ceil((earliest_s - origin_s) * fps), frames_ahead_ + 1.0);
  const double start_s = origin_s + frame / fps;
  if (rig_.waiting_motion->start_at(start_s)) {
    spdlog::info(
        "serve{}: a client read {}'s metadata: the motion starts with frame {:.0f} of its stream (pose time {:.3f} s)",
        log_tag_, sensor_.identity().prod_sn, frame, start_s);
  }
}

void VirtualSensor::start() {
  http_.start();
  subscription_ = sensor_.subscribe([this](const Sensor::StreamConfigPtr& config) { streamer_.apply(config); });
  if (lock_step_ && rig_.live) {
    pose_subscription_ = rig_.live->subscribe([this](const PoseMessage& pose) { streamer_.advance_to(pose.time_ns); });
  } else if (rig_.live) {
    pose_subscription_ = rig_.live->subscribe([this](const PoseMessage&) { streamer_.pose_arrived(); });
  }
  stats_pump_ = std::jthread([this](std::stop_token stop) { pump_stats(stop); });
}

// Stats go to the sensor from a thread of their own: the send clock must never wait for the
// sensor's lock, which HTTP threads hold.
void VirtualSensor::pump_stats(const std::stop_token& stop) {
  run_at_normal_priority(0);  // not the send clock's SCHED_FIFO
  std::mutex mutex;
  std::condition_variable_any tick;
  std::unique_lock lock(mutex);
  while (!tick.wait_for(lock, stop, std::chrono::seconds(1), [] { return false; })) {
    if (stop.stop_requested()) break;
    sensor_.set_stream_stats(streamer_.stats());
  }
}

void VirtualSensor::stop_streaming() {
  fault_timer_.cancel();
  streamer_.stop();
}

void VirtualSensor::stop() {
  if (stats_pump_.joinable()) {
    stats_pump_.request_stop();
    stats_pump_.join();
  }
  if (subscription_ != 0) {
    sensor_.unsubscribe(subscription_);
    subscription_ = 0;
  }
  if (pose_subscription_ != 0) {
    rig_.live->unsubscribe(pose_subscription_);
    pose_subscription_ = 0;
  }
  http_.stop();
}

}  // namespace lidartwin
