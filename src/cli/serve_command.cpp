// `lidartwin serve`: the daemon. A Sensor (state machine) behind the HTTP API, and a Streamer that
// follows the sensor's active config; Ctrl-C or SIGTERM stops both and exits 0.
#include <algorithm>
#include <chrono>
#include <csignal>
#include <iostream>
#include <memory>
#include <thread>

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <asio.hpp>

#include "cli/command.h"
#include "cli/format_validators.h"
#include "cli/rig_file.h"
#include "cli/sensor_physics.h"
#include "cli/serve_inputs.h"
#include "cli/serve_motion.h"
#include "cli/unit_twin.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/fault/fault_plan.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/pose/live_poses.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/rig/pose_receiver.h"
#include "lidartwin/rig/virtual_sensor.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin::cli {
namespace {

void setup_logging(const std::string& level) {
  auto logger = spdlog::stderr_color_mt("lidartwin");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  spdlog::set_level(spdlog::level::from_str(level));
}

// The bind error's remedies (protocol doc 2.1) as one line on stderr.
int report_bind_error(const BindError& error) {
  std::string message = error.what();
  std::replace(message.begin(), message.end(), '\n', ' ');
  std::cerr << "lidartwin: " << message << std::endl;
  return 2;
}

// Runs until SIGINT/SIGTERM: the signal stops the sensors' streamers, which leaves the io_context
// without work, so run() returns; then the sensors' HTTP servers and stats stop. `signals` was made
// before the sensors started answering, so a signal sent as soon as they answer is not lost.
int run_daemon(asio::io_context& io, asio::signal_set& signals, std::vector<std::unique_ptr<VirtualSensor>>& sensors,
               PoseReceiver* receiver) {
  signals.async_wait([&sensors, receiver](const asio::error_code& error, int signal_number) {
    if (error) return;
    spdlog::info("serve: {} received, stopping", signal_number == SIGINT ? "SIGINT" : "SIGTERM");
    for (auto& sensor : sensors) sensor->stop_streaming();
    if (receiver) receiver->stop();
  });
  // The send clock's wake-ups should not be rounded up by the default 50 us timer slack.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  io.run();
  for (auto& sensor : sensors) sensor->stop();
  spdlog::info("serve: stopped");
  return 0;
}

// The send clock on a busy host (protocol doc 1 item 12): as SCHED_FIFO it preempts casting and
// everything else the moment a deadline comes. Needs root or CAP_SYS_NICE; without it, casting
// runs niced instead. The HTTP threads, started before, keep the normal policy.
bool raise_send_clock_priority() {
  sched_param param{};
  param.sched_priority = 10;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
}

// Whether raise_send_clock_priority() will succeed, asked of a throwaway thread so that the
// casting threads can be niced from the start when it will not.
bool send_clock_can_be_realtime() {
  bool can = false;
  std::thread([&can] { can = raise_send_clock_priority(); }).join();
  return can;
}

std::string to_spec_joined(const std::vector<std::string>& specs) {
  std::string joined;
  for (const std::string& spec : specs) joined += (joined.empty() ? "" : ",") + spec;
  return joined;
}

VirtualSensorSetup sensor_setup(const ServeFlags& flags, const SensorChoice& sensor,
                                const std::array<uint8_t, 4>& address, int render_nice) {
  const SensorProfile& profile = sensor.profile;
  VirtualSensorSetup setup;
  setup.identity = make_identity(sensor, address, flags.serial_number);
  setup.sensor.state_file = flags.state_file;
  setup.sensor.config_overrides = config_overrides(flags, sensor.unit);
  setup.http.address = flags.address;
  setup.http.port = flags.http_port;
  setup.streamer.source_address = address;
  setup.streamer.record_dir = flags.record_dir;
  setup.streamer.spin_us = flags.spin_us;
  setup.streamer.coalesce_us = flags.coalesce_us;
  setup.streamer.contention = flags.contention == "always"  ? StreamerOptions::Contention::kAlways
                              : flags.contention == "never" ? StreamerOptions::Contention::kNever
                                                            : StreamerOptions::Contention::kAuto;
  setup.streamer.render_nice = render_nice;
  setup.max_range_m = profile.max_range_m;
  SensorPhysics physics = sensor_physics(profile, flags.ideal);
  setup.chain = std::move(physics.chain);
  setup.seed = flags.seed;
  setup.mounting = mounting(flags);
  setup.per_column_poses = flags.per_column_poses;
  setup.imu_noise = physics.imu;
  setup.stamp_pose_clock = flags.stamp_pose_clock;
  // Several --fault flags make one plan: a key given twice is an error, as within one flag.
  if (!flags.faults.empty()) setup.faults = fault_plan_from_spec(to_spec_joined(flags.faults), flags.seed);
  if (live(flags)) {
    setup.streamer.lock_step = flags.lock_step;
    setup.streamer.cast_ahead_ms = flags.cast_ahead_ms;
    setup.streamer.withhold_unposed = live_pose_options(flags).timeout == PoseTimeout::kStandby;
  }
  return setup;
}

int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// A unit's firmware older than 2.4: clients refuse it, as they would refuse the unit.
void warn_old_firmware(const SensorChoice& choice) {
  if (!choice.unit) return;
  spdlog::info("serve: {}", choice.profile.source);
  const std::string& image_rev = choice.unit->sensor_info.image_rev;
  const auto version = firmware_version(image_rev);
  if (version && *version < std::pair{2, 4}) {
    spdlog::warn(
        "serve: the unit's firmware ({}) is older than 2.4: SDK 0.16 and later refuse it (\"Please upgrade "
        "your sensor to FW 2.4 or later\"), as they would refuse the unit",
        image_rev);
  }
}

// One sensor of the daemon before it starts: the command line's, or an entry of a rig file.
struct PlannedSensor {
  RigSensor entry;
  SensorChoice choice;
  VirtualSensorSetup setup;
  // What a message about this sensor's flags starts with: "--rig rig.json: sensor \"left\": ".
  std::string context;
};

std::vector<PlannedSensor> plan_sensors(const ServeFlags& flags, int render_nice) {
  std::vector<RigSensor> entries;
  if (flags.rig.empty()) {
    entries.push_back({"", flags});
  } else {
    entries = load_rig(find_input("--rig", flags.rig), flags);  // as given, else in the source tree (rigs/)
  }
  std::vector<PlannedSensor> planned;
  for (RigSensor& entry : entries) {
    const std::string context =
        flags.rig.empty() ? std::string() : fmt::format("--rig {}: sensor \"{}\": ", flags.rig, entry.name);
    try {
      SensorChoice choice = load_sensor(entry.flags.profile);
      VirtualSensorSetup setup = sensor_setup(entry.flags, choice, parse_address(entry.flags.address), render_nice);
      setup.name = entry.name;
      planned.push_back({std::move(entry), std::move(choice), std::move(setup), context});
    } catch (const InputError& e) {
      throw InputError(context + e.what());
    }
  }
  return planned;
}

int serve(const ServeFlags& flags) {
  setup_logging(flags.log_level);
  const bool realtime = send_clock_can_be_realtime();
  std::vector<PlannedSensor> planned = plan_sensors(flags, realtime ? 0 : 5);
  const auto scene_file = scene_path(flags);
  const Scene scene = Scene::load(scene_file);
  // The rig's time zero: a trajectory starts here, live poses are placed on it as they arrive.
  // Every sensor of a rig shares it, so their columns agree in time as on a vehicle with PTP.
  const int64_t epoch_steady_ns = steady_now_ns();
  const Motion motion = load_motion(flags, epoch_steady_ns);
  for (const PlannedSensor& p : planned) {
    spdlog::info("serve: {}{} ({}) in {} ({} triangles), {}", p.entry.name.empty() ? "" : p.entry.name + ": ",
                 p.choice.profile.prod_line, p.choice.profile.name, scene_file.string(), scene.triangle_count(),
                 motion.description);
    warn_old_firmware(p.choice);
  }

  asio::io_context io;
  // From here SIGINT/SIGTERM are caught (and held until run_daemon waits for them): a client or
  // supervisor that stops the daemon as soon as it answers gets a clean stop, not exit 143.
  asio::signal_set signals(io, SIGINT, SIGTERM);
  // One pool for every sensor: its runs take turns, a packet's worth of columns at a time.
  WorkerPool pool(flags.threads, realtime ? 0 : 5);
  // One time base for every sensor: their timestamps, HTTP clocks and telemetry agree.
  const RigContext rig{io,
                       scene,
                       motion.poses(),
                       pool,
                       flags.lock_step ? 0 : epoch_steady_ns,
                       motion.live.get(),
                       motion.waits_for_client ? motion.trajectory.get() : nullptr,
                       std::make_shared<const TimeBase>(TimeBase::from_host())};
  std::unique_ptr<PoseReceiver> receiver;
  if (motion.live) {
    // A multicast group is joined on --address's interface (0.0.0.0: the routing table's choice).
    receiver = std::make_unique<PoseReceiver>(io, *motion.live, pose_udp_endpoint(flags),
                                              asio::ip::make_address_v4(flags.address));
  }
  std::vector<std::unique_ptr<VirtualSensor>> sensors;
  for (PlannedSensor& p : planned) {
    try {
      sensors.push_back(std::make_unique<VirtualSensor>(rig, std::move(p.setup)));
    } catch (const InputError& e) {
      // The streamer names --record itself; the sensor's config errors come from these flags.
      const std::string message = e.what();
      if (message.starts_with("--record")) throw InputError(p.context + message);
      throw InputError(
          p.context + (p.choice.unit ? "--profile " + p.entry.flags.profile + " (the unit's config)/" : std::string()) +
          "--lidar-mode/--udp-profile/--state-file: " + message);
    }
  }
  try {
    for (auto& sensor : sensors) sensor->start();
  } catch (const BindError& e) {
    return report_bind_error(e);
  }
  if (receiver) receiver->start();
  for (size_t i = 0; i < sensors.size(); ++i) {
    const SensorIdentity& identity = sensors[i]->sensor().identity();
    spdlog::info("serve: {}sensor {} sn {} answering on http://{}:{}/api/v1/",
                 planned[i].entry.name.empty() ? "" : planned[i].entry.name + ": ", identity.prod_line,
                 identity.prod_sn, planned[i].entry.flags.address, sensors[i]->http().port());
  }
  raise_send_clock_priority();
  spdlog::info("serve: send clock runs {}",
               realtime ? "SCHED_FIFO" : "at normal priority (no CAP_SYS_NICE), casting niced");
  return run_daemon(io, signals, sensors, receiver.get());
}

void setup_serve(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<ServeFlags>();
  CLI::App* sub = app.add_subcommand("serve", "Run a virtual sensor: HTTP API and UDP lidar/IMU streams");
  sub->add_option("--profile", flags->profile,
                  "sensor profile name or .json path, or a unit's metadata .json (a twin of that unit)")
      ->capture_default_str();
  sub->add_option("--scene", flags->scene, "glTF scene (default scenes/plant.glb)");
  auto* trajectory = sub->add_option("--trajectory", flags->trajectory,
                                     "TUM trajectory (default scenes/plant_inspection.tum with the default scene)");
  auto* pose_flag = sub->add_option("--pose", flags->pose, "a fixed pose \"x y z qx qy qz qw\"")->excludes(trajectory);
  sub->add_option("--address", flags->address, "the sensor's IPv4 address (HTTP and UDP source)")
      ->capture_default_str();
  sub->add_option("--http-port", flags->http_port, "HTTP port (80 as on a real sensor; 0 = any)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  sub->add_option("--seed", flags->seed, "noise seed")->capture_default_str();
  add_ideal_flag(*sub, flags->ideal);
  sub->add_option("--serial-number", flags->serial_number,
                  "prod_sn, 1 to 12 digits (default 122201 + digits from --address; give each sensor of a "
                  "rig its own when they all bind 0.0.0.0)")
      ->check(serial_number_validator());
  sub->add_option("--record", flags->record_dir,
                  "also write every sent packet to DIR/capture.pcap + DIR/metadata.json");
  sub->add_option("--lidar-mode", flags->lidar_mode, "initial lidar_mode, e.g. 1024x10")->check(lidar_mode_validator());
  sub->add_option("--udp-profile", flags->udp_profile, "initial udp_profile_lidar")->check(udp_profile_validator());
  sub->add_option("--state-file", flags->state_file, "where persisted config and user data live");
  sub->add_option("--threads", flags->threads, "ray casting threads (0 = all cores)")->check(CLI::Range(0, 1024));
  sub->add_option("--spin-us", flags->spin_us,
                  "wake this early and spin to each packet's deadline while the host's CPUs are not contended "
                  "(0 = sleep only)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  sub->add_option("--coalesce-us", flags->coalesce_us,
                  "while the host's CPUs are contended and casting falls behind, send the packets due within this "
                  "long of each other together, the earlier ones held back; doubling each second casting still "
                  "falls behind, up to 8 times and 20 ms (0 = one wake-up per packet)")
      ->check(CLI::Range(0, 10000))
      ->capture_default_str();
  sub->add_option("--contention", flags->contention,
                  "whether the host's CPUs count as contended (no --spin-us, --coalesce-us on): auto follows "
                  "/proc/pressure/cpu; always, never")
      ->check(CLI::IsMember({"auto", "always", "never"}))
      ->capture_default_str();
  sub->add_option("--trajectory-end", flags->trajectory_end,
                  "what the trajectory's end means: hold (the last pose), loop, stop (streaming); default: loop "
                  "if it closes (last pose within 1 cm and 0.057 deg of the first), else hold")
      ->excludes(pose_flag);
  sub->add_option("--motion-start", flags->motion_start,
                  "when the trajectory starts: daemon (when it starts), configured (when a client first "
                  "reinitializes the sensor or, if it never does, reads sensor/metadata)")
      ->capture_default_str();
  sub->add_flag("--live-poses", flags->live_poses,
                "poses arrive live: POST /lidartwin/v1/pose (and UDP with --pose-udp); docs/live-poses.md")
      ->excludes(trajectory);
  sub->add_option("--pose-udp", flags->pose_udp,
                  "[ADDR:]PORT: listen for UDP pose messages (implies --live-poses); a multicast ADDR "
                  "(239.x.y.z) joins that group on --address's interface, so a rig's processes share one stream")
      ->excludes(trajectory);
  auto* pose_clock =
      sub->add_option("--pose-clock", flags->pose_clock, "the clock of pose times: sender, monotonic, realtime, tai")
          ->check(CLI::IsMember({"sender", "monotonic", "realtime", "tai"}))
          ->capture_default_str();
  sub->add_flag("--lock-step", flags->lock_step,
                "the simulator owns time: packets are stamped with the poses' times and sent as those times "
                "arrive (implies --live-poses)")
      ->excludes(trajectory)
      ->excludes(pose_clock);
  sub->add_flag("--stamp-pose-clock", flags->stamp_pose_clock,
                "with live poses: stamp packets on the poses' clock (a simulator's time) instead of the "
                "timestamp_mode's, paced on the host's; streaming starts with the first pose")
      ->excludes(trajectory)
      ->excludes("--lock-step");
  sub->add_option("--pose-extrapolate-ms", flags->pose_extrapolate_ms,
                  "extrapolate live poses up to this far past the newest")
      ->check(CLI::Range(0.0, 10'000.0))
      ->capture_default_str();
  sub->add_option("--pose-timeout", flags->pose_timeout,
                  "past the extrapolation: hold (freeze the pose), invalid (status 0), standby (send nothing)")
      ->check(CLI::IsMember({"hold", "invalid", "standby"}))
      ->capture_default_str();
  sub->add_option("--cast-ahead-ms", flags->cast_ahead_ms,
                  "with live poses: cast each packet this long before it is due, and again if a pose arrives "
                  "before then (more: safer on a busy host, more packets cast twice)")
      ->check(CLI::Range(0.1, 1000.0))
      ->capture_default_str();
  sub->add_option("--mount", flags->mount,
                  "the sensor on the vehicle whose poses arrive (vehicle_from_sensor \"x y z qx qy qz qw\")");
  sub->add_flag("!--no-per-column-poses", flags->per_column_poses,
                "cast every column of a frame from the frame's first pose (shows what motion distortion does)");
  sub->add_option("--fault", flags->faults,
                  "inject faults, e.g. loss=0.01,loss_burst=3,reorder=0.01,reset_at=10,seed=7 (repeatable; "
                  "docs/fault-injection.md; GET/PUT /lidartwin/v1/faults at run time)");
  auto* rig = sub->add_option("--rig", flags->rig,
                              "a rig file (docs/rig.md): several sensors, each with its own address, profile and "
                              "mounting, in this one process, sharing the scene, the motion and the time base");
  for (const std::string& name : per_sensor_flags()) rig->excludes(name);
  sub->add_option("--log-level", flags->log_level, "trace, debug, info, warn, error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  sub->callback([&run, flags] { run = [flags] { return serve(*flags); }; });
}

const RegisterCommand registered_serve("serve", setup_serve);

}  // namespace
}  // namespace lidartwin::cli
