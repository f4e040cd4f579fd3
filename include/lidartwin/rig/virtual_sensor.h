#pragma once
// One virtual sensor as a client sees it: the sensor state machine behind its HTTP API, and a
// streamer that follows the active config with packets from the forward model. A rig holds several,
// sharing one scene, one motion, one io_context and one worker pool.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include <asio.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/fault/fault_control.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/http_api/http_server.h"
#include "lidartwin/pose/live_poses.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/pose/trajectory_playback.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/scene/scene.h"
#include "lidartwin/sensor/sensor.h"
#include "lidartwin/streamer/streamer.h"

namespace lidartwin {

// What the sensors of a rig share. All must outlive the sensors.
struct RigContext {
  asio::io_context& io;  // runs every sensor's send clock
  const Scene& scene;
  const PoseSource& poses;
  WorkerPool& pool;
  // The steady-clock instant at which the pose source's time is poses.start_s(): the rig's time
  // zero, so that sensors started together see the same motion at the same instant.
  int64_t epoch_steady_ns = 0;
  // When poses arrive live (then `poses` is this, or mounts it): each sensor's HTTP server answers
  // /lidartwin/v1/pose with it.
  LivePoses* live = nullptr;
  // A trajectory whose motion waits for a client (serve --motion-start configured; then `poses` is
  // this): the first client to configure any of the rig's sensors starts it for all.
  TrajectoryPlayback* waiting_motion = nullptr;
  // The clocks every sensor's packets and HTTP API report time on (sensor/time_base.h), one for
  // the rig so that its sensors' timestamps agree. Null: the rig reads the host's when it starts.
  std::shared_ptr<const TimeBase> time = nullptr;
};

// Who one sensor is and how it is reached.
struct VirtualSensorSetup {
  std::string name = {};         // a rig's sensor, named in its log lines (log_tag.h); empty: a lone sensor
  SensorIdentity identity;       // product, serial number and beams as served
  SensorOptions sensor;          // state file, config overrides
  HttpServerOptions http;        // its address and port
  StreamerOptions streamer;      // its source address, --record, pacing
  double max_range_m = 100.0;    // the profile's range limit (casting stops 1 m beyond it)
  EffectChain chain;             // the profile's physics
  uint64_t seed = 0;             // noise seed
  Pose mounting;                 // vehicle_from_sensor: where the rig's motion carries this sensor
  bool per_column_poses = true;  // false: every column of a frame cast from the frame's first pose
  ImuNoise imu_noise;            // the profile's IMU errors
  // With live poses: packets stamped on the poses' clock (a simulator's time), paced on the host's.
  bool stamp_pose_clock = false;
  // Faults injected from the start (serve --fault); /lidartwin/v1/faults changes them at run time.
  FaultPlan faults;
};

class VirtualSensor {
 public:
  // Throws InputError for a config the sensor refuses (state file, overrides) or a socket the
  // streamer cannot bind.
  VirtualSensor(const RigContext& rig, VirtualSensorSetup setup);
  ~VirtualSensor();  // stop()
  VirtualSensor(const VirtualSensor&) = delete;
  VirtualSensor& operator=(const VirtualSensor&) = delete;

  // Binds the HTTP server (throws BindError) and starts following the sensor's config: from here
  // the rig's io_context streams for this sensor, and its stream stats reach the sensor's telemetry
  // once a second.
  void start();
  // On the io thread (or before it runs): stops streaming, so that io_context::run() can return
  // once every sensor has stopped.
  void stop_streaming();
  // After the io_context has stopped: stops the stats, the config subscription and the HTTP server.
  // Idempotent.
  void stop();

  Sensor& sensor() { return sensor_; }
  const HttpServer& http() const { return http_; }
  FaultControl& faults() { return faults_; }

  // The HTTP server's handler of /lidartwin/v1/ (faults, and live poses when they arrive live).
  ApiResponse lidartwin_endpoint(const ApiRequest& request);
  // The streamer's: a sensor fault of the plan is due (io thread).
  void on_sensor_fault(SensorFaultEvent event);
  // The sensor's: a client reinitialized it or read its metadata (the client's HTTP thread).
  void on_client(ClientEvent event);

 private:
  std::unique_ptr<ForwardModel> make_model(const StreamConfig& config, int64_t start_steady_ns, uint64_t origin_ns);
  void pump_stats(const std::stop_token& stop);
  double rig_time_s(int64_t steady_ns) const;
  void on_session(double pose_origin_s, int fps);

  // Where the current session's frames sit on the rig's clock, for a motion a metadata read starts.
  struct SessionFrames {
    double pose_origin_s = 0.0;
    int fps = 10;
  };

  RigContext rig_;
  std::string log_tag_;  // " (roof)" after "serve" in a rig's sensor's log lines
  MountedPoses poses_;   // the rig's motion carrying this sensor
  bool per_column_poses_;
  bool lock_step_;
  ImuNoise imu_noise_;
  bool stamp_pose_clock_;
  double max_range_m_;
  EffectChain chain_;
  uint64_t seed_;
  int frames_ahead_;  // how far the streamer casts ahead of its send clock
  // A client's reinit asked for the waiting motion to start with the next session's frame 0.
  std::atomic<bool> start_motion_with_session_{false};
  mutable std::mutex session_mutex_;
  std::optional<SessionFrames> session_frames_;  // guarded by session_mutex_
  FaultControl faults_;                          // before the server and streamer, which read it
  asio::steady_timer fault_timer_;               // ends an injected STANDBY or ERROR
  Sensor sensor_;
  HttpServer http_;
  Streamer streamer_;
  int subscription_ = 0;
  int pose_subscription_ = 0;
  std::jthread stats_pump_;
};

}  // namespace lidartwin
