#include "lidartwin/rig/virtual_sensor.h"

#include <condition_variable>
#include <mutex>

#include "lidartwin/frame/forward_model.h"
#include "lidartwin/json/json_reader.h"
#include "lidartwin/rig/fault_api.h"
#include "lidartwin/rig/pose_api.h"

namespace lidartwin {

namespace {
HttpServerOptions with_extensions(HttpServerOptions http, VirtualSensor& sensor, FaultControl& faults) {
  http.lidartwin_api = [&sensor](const ApiRequest& request) { return sensor.lidartwin_endpoint(request); };
  http.faults = &faults;
  return http;
}
StreamerOptions with_faults(StreamerOptions options, VirtualSensor& sensor, FaultControl& faults) {
  options.faults = &faults;
  options.on_sensor_fault = [&sensor](SensorFaultEvent event) { sensor.on_sensor_fault(event); };
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
    : rig_(rig),
      poses_(rig.poses, setup.mounting),
      per_column_poses_(setup.per_column_poses),
      lock_step_(setup.streamer.lock_step),
      imu_noise_(setup.imu_noise),
      stamp_pose_clock_(setup.stamp_pose_clock && rig.live != nullptr),
      max_range_m_(setup.max_range_m),
      chain_(std::move(setup.chain)),
      seed_(setup.seed),
      faults_(std::move(setup.faults)),
      fault_timer_(rig.io),
      sensor_(std::move(setup.identity), std::move(setup.sensor)),
      http_(sensor_, with_extensions(std::move(setup.http), *this, faults_)),
      streamer_(
          rig.io,
          [this](const StreamConfig& config, int64_t start_steady_ns, uint64_t origin_ns) {
            return make_model(config, start_steady_ns, origin_ns);
          },
          with_faults(with_pose_clock(std::move(setup.streamer), rig.live, setup.stamp_pose_clock), *this, faults_)) {}

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
                                                        uint64_t origin_ns) const {
  const LidarDataFormat& format = config.metadata.format;
  ForwardModelSetup setup;
  setup.render = {config.metadata.beams, format, max_range_m_, chain_, seed_, config.signal_multiplier};
  setup.origin_ns = origin_ns;
  setup.pose_origin_s = rig_.poses.start_s() + static_cast<double>(start_steady_ns - rig_.epoch_steady_ns) * 1e-9;
  setup.init_id = config.init_id;
  setup.prod_sn = config.prod_sn;
  setup.per_column_poses = per_column_poses_;
  setup.imu_noise = imu_noise_;
  return std::make_unique<ForwardModel>(rig_.scene, poses_, std::move(setup), rig_.pool);
}

void VirtualSensor::start() {
  http_.start();
  subscription_ = sensor_.subscribe([this](const Sensor::StreamConfigPtr& config) { streamer_.apply(config); });
  if (lock_step_ && rig_.live) {
    pose_subscription_ = rig_.live->subscribe([this](const PoseMessage& pose) { streamer_.advance_to(pose.time_ns); });
  } else if (stamp_pose_clock_) {
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
