// `lidartwin record`: a capture as a real sensor would produce it, rendered offline as fast as the
// machine allows: DIR/capture.pcap, DIR/metadata.json and the ground truth DIR/poses.tum.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <signal.h>
#include <unistd.h>
#include <csignal>

#include <fmt/ranges.h>

#include "cli/command.h"
#include "cli/format_validators.h"
#include "cli/rig_file.h"
#include "cli/sensor_physics.h"
#include "cli/serve_motion.h"
#include "cli/unit_twin.h"
#include "lidartwin/error.h"
#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/random/counter_rng.h"
#include "lidartwin/record/recorder.h"

namespace lidartwin::cli {
namespace {

struct RecordFlags {
  std::string profile;
  std::string scene;
  std::string trajectory;
  std::string pose;
  std::string mode = "1024x10";
  std::string udp_profile = "RNG19_RFL8_SIG16_NIR16";
  // Which of --mode, --udp-profile, --columns-per-packet were given: a twin takes its unit's value
  // for the others.
  bool mode_given = false;
  bool udp_profile_given = false;
  bool columns_given = false;
  int frames = 10;
  uint64_t seed = 0;
  std::string out;
  int threads = 0;
  int columns_per_packet = 16;
  bool ideal = false;
  double uptime_s = kDefaultUptimeS;
  std::string rig;             // --rig FILE: a capture per sensor of the rig (docs/rig.md), in OUT/<name>/
  std::string trajectory_end;  // hold, loop, stop; empty: loop if it closes, else hold (as serve)
};

// What moves the recorded sensor (or the rig's vehicle): a fixed pose, or the trajectory played as
// --trajectory-end says.
struct RecordMotion {
  std::unique_ptr<PoseSource> poses;
  std::optional<double> stops_after_s;  // --trajectory-end stop: the trajectory's duration
  // The frames to record at `fps`: those asked for, or those the trajectory lasts if it stops first.
  int frames(int requested, int fps) const {
    if (!stops_after_s) return requested;
    const int lasts = static_cast<int>(std::floor(*stops_after_s * fps + 1e-6));
    if (lasts < 1) {
      throw InputError(fmt::format("--trajectory-end stop: the trajectory lasts {} s, less than one frame at {} Hz",
                                   *stops_after_s, fps));
    }
    return std::min(requested, lasts);
  }
};

RecordMotion load_motion(const RecordFlags& flags) {
  if (flags.trajectory.empty() == flags.pose.empty()) throw InputError("record: give one of --trajectory or --pose");
  if (!flags.pose.empty()) {
    try {
      return {std::make_unique<StaticPose>(parse_pose(flags.pose)), std::nullopt};
    } catch (const InputError& e) {
      throw InputError(std::string("--pose: ") + e.what());
    }
  }
  const Trajectory trajectory = Trajectory::load_tum(flags.trajectory);
  if (trajectory.start_s() < 0.0) {
    throw InputError("--trajectory " + flags.trajectory + ": starts at a negative time (" +
                     std::to_string(trajectory.start_s()) + " s); times become sensor timestamps in ns");
  }
  const TrajectoryEndChoice end = choose_trajectory_end(flags.trajectory_end, trajectory);
  std::fprintf(stderr, "record: at its end the trajectory %s (%s)\n",
               std::string(end.end == TrajectoryEnd::kStop ? "stops the capture" : meaning(end.end)).c_str(),
               end.why.c_str());
  // A looped trajectory is played by TrajectoryPoses itself, whose span() gives the IMU its exact
  // motion (TrajectoryPlayback, which can hold, has none).
  if (end.end == TrajectoryEnd::kLoop) return {std::make_unique<TrajectoryPoses>(trajectory), std::nullopt};
  RecordMotion motion{std::make_unique<TrajectoryPlayback>(trajectory, end.end, false), std::nullopt};
  if (end.end == TrajectoryEnd::kStop) motion.stops_after_s = trajectory.duration_s();
  return motion;
}

// The config recorded: the flags; for a twin of a unit, the unit's mode, profile and columns per
// packet where no flag says otherwise.
nlohmann::json record_config(const RecordFlags& flags, const SensorChoice& sensor) {
  nlohmann::json config = default_config_params();
  config["lidar_mode"] = flags.mode;
  config["udp_profile_lidar"] = flags.udp_profile;
  config["columns_per_packet"] = flags.columns_per_packet;
  if (!sensor.unit) return config;
  nlohmann::json unit = unit_start_config(*sensor.unit);
  if (flags.mode_given) unit.erase("lidar_mode");
  if (flags.udp_profile_given) unit.erase("udp_profile_lidar");
  if (flags.columns_given) unit.erase("columns_per_packet");
  config.update(unit);
  return config;
}

// Who recorded: a twin is its unit (serial, firmware, and the unit file's initialization_id, so
// that the capture decodes with the unit's own metadata file, as a capture of that session would).
SensorInfo record_sensor_info(const RecordFlags& flags, const SensorChoice& sensor) {
  SensorInfo info;
  info.prod_line = sensor.profile.prod_line;
  info.prod_pn = sensor.profile.prod_pn;
  info.prod_sn = "992200000001";  // fixed: captures of one profile look like one unit
  info.image_rev = "ousteros-image-prod-bootes-v3.1.0+20240426041747";
  info.build_rev = "v3.1.0";
  info.build_date = "2024-04-26T02:34:31Z";
  // 24 bits, never 0, a pure function of the seed (6.2).
  info.initialization_id = static_cast<uint32_t>(rng_detail::mix64(flags.seed ^ 0x696E69745F6964ULL) % 0xFFFFFFu) + 1;
  if (sensor.unit) {
    const SensorInfo& unit = sensor.unit->sensor_info;
    if (!unit.prod_sn.empty()) info.prod_sn = unit.prod_sn;
    if (!unit.image_rev.empty()) info.image_rev = unit.image_rev;
    if (!unit.build_rev.empty()) info.build_rev = unit.build_rev;
    if (!unit.build_date.empty()) info.build_date = unit.build_date;
    if (unit.initialization_id != 0) info.initialization_id = unit.initialization_id;
  }
  return info;
}

Metadata make_record_metadata(const RecordFlags& flags, const SensorChoice& sensor) {
  const SensorProfile& profile = sensor.profile;
  const nlohmann::json config = record_config(flags, sensor);
  const std::string mode = config.at("lidar_mode").get<std::string>();
  const auto& modes = profile.lidar_modes;
  if (std::find(modes.begin(), modes.end(), mode) == modes.end()) {
    throw InputError(fmt::format("--mode {}: not a lidar mode of {}; expected one of {}", mode, profile.name,
                                 fmt::join(modes, ", ")));
  }
  try {
    Metadata metadata = make_metadata(record_sensor_info(flags, sensor), profile.beams, config);
    const PacketFormat validated(metadata.format);  // e.g. a packet larger than a datagram
    return metadata;
  } catch (const InputError& e) {
    throw InputError(std::string("--mode/--udp-profile/--columns-per-packet: ") + e.what());
  }
}

// "\r[=====     ] 12/100 frames, 3.1x real time" on stderr when it is a terminal; in a log, a plain
// line at every tenth of the frames ("record: 12/100 frames, 3.1x real time").
class ProgressBar {
 public:
  ProgressBar(int total, int fps) : total_(total), fps_(fps), tty_(isatty(STDERR_FILENO) != 0) {}
  void update(int done) const {
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (!tty_) {
      const int tenth = done * 10 / total_;
      if (tenth == printed_tenth_) return;
      printed_tenth_ = tenth;
      std::fprintf(stderr, "record: %d/%d frames, %.1fx real time\n", done, total_,
                   elapsed > 0 ? done / (fps_ * elapsed) : 0.0);
      return;
    }
    const int width = 30;
    const int filled = done * width / total_;
    std::fprintf(stderr, "\r[%s%s] %d/%d frames, %.1fx real time",
                 std::string(static_cast<size_t>(filled), '=').c_str(),
                 std::string(static_cast<size_t>(width - filled), ' ').c_str(), done, total_,
                 elapsed > 0 ? done / (fps_ * elapsed) : 0.0);
    if (done == total_) std::fprintf(stderr, "\n");
  }

 private:
  int total_;
  int fps_;
  bool tty_;
  mutable int printed_tenth_ = 0;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// SIGINT/SIGTERM end the capture after the frame being rendered (Recording::stop).
std::atomic<bool> stop_requested{false};
static_assert(std::atomic<bool>::is_always_lock_free, "set from a signal handler");
extern "C" void request_stop(int) { stop_requested.store(true); }

void catch_stop_signals() {
  struct sigaction action {};
  action.sa_handler = request_stop;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

// --rig: each sensor recorded in turn from the same vehicle motion, carried by its mounting, into
// OUT/<name>/, with its own metadata (its serial number as serve gives it, its seed, mode and
// profile) and ground truth. Frame k of every sensor starts at the same time: the captures share
// one time base. The rig file's serve-only keys (http_port, state_file, record, fault) are unused.
int run_record_rig(const RecordFlags& flags) {
  ServeFlags base;
  base.seed = flags.seed;
  const auto rig_file = find_input("--rig", flags.rig);
  const std::vector<RigSensor> sensors = load_rig(rig_file, base);
  struct Planned {
    RecordFlags flags;
    SensorChoice choice;
    Metadata metadata;
    Pose mounting;
  };
  std::vector<Planned> planned;
  for (const RigSensor& sensor : sensors) {  // every sensor checked before any is recorded
    try {
      RecordFlags f = flags;
      f.profile = sensor.flags.profile;
      f.seed = sensor.flags.seed;
      f.out = (std::filesystem::path(flags.out) / sensor.name).string();
      if (!sensor.flags.lidar_mode.empty()) {
        f.mode = sensor.flags.lidar_mode;
        f.mode_given = true;
      }
      if (!sensor.flags.udp_profile.empty()) {
        f.udp_profile = sensor.flags.udp_profile;
        f.udp_profile_given = true;
      }
      SensorChoice choice = load_sensor(f.profile);
      Metadata metadata = make_record_metadata(f, choice);
      metadata.sensor_info.prod_sn =
          make_identity(choice, parse_address(sensor.flags.address), sensor.flags.serial_number).prod_sn;
      planned.push_back({std::move(f), std::move(choice), std::move(metadata), mounting(sensor.flags)});
    } catch (const InputError& e) {
      throw InputError(fmt::format("--rig {}: sensor \"{}\": {}", flags.rig, sensor.name, e.what()));
    }
  }
  const RecordMotion vehicle = load_motion(flags);
  const Scene scene = Scene::load(flags.scene);
  catch_stop_signals();
  for (Planned& p : planned) {
    const MountedPoses poses(*vehicle.poses, p.mounting);
    SensorPhysics physics = sensor_physics(p.choice.profile, flags.ideal);
    const int planned_frames = vehicle.frames(flags.frames, p.metadata.format.fps);
    const ProgressBar bar(planned_frames, p.metadata.format.fps);
    const int frames =
        record({scene, poses, p.choice.profile.max_range_m, std::move(physics.chain), p.metadata, p.flags.seed,
                flags.threads, planned_frames, p.flags.out, physics.imu, flags.uptime_s, &stop_requested},
               [&bar](int done) { bar.update(done); });
    if (frames < planned_frames) {
      std::fprintf(stderr, "\nrecord: interrupted after %d of %d frames of %s; %s holds them, every file complete\n",
                   frames, planned_frames, p.flags.out.c_str(), p.flags.out.c_str());
      return 130;
    }
    std::printf("recorded %d frames of %s (%s, sn %s) to %s\n", frames, p.choice.profile.name.c_str(),
                p.metadata.config_params.value("lidar_mode", "").c_str(), p.metadata.sensor_info.prod_sn.c_str(),
                p.flags.out.c_str());
  }
  return 0;
}

int run_record(const RecordFlags& flags) {
  if (!flags.rig.empty()) return run_record_rig(flags);
  if (flags.profile.empty()) throw InputError("record: give --profile (or --rig)");
  const SensorChoice sensor = load_sensor(flags.profile);
  const SensorProfile& profile = sensor.profile;
  const Metadata metadata = make_record_metadata(flags, sensor);
  const RecordMotion motion = load_motion(flags);
  const Scene scene = Scene::load(flags.scene);
  SensorPhysics physics = sensor_physics(profile, flags.ideal);
  const int planned_frames = motion.frames(flags.frames, metadata.format.fps);
  const ProgressBar bar(planned_frames, metadata.format.fps);
  catch_stop_signals();
  const int frames = record({scene, *motion.poses, profile.max_range_m, std::move(physics.chain), metadata, flags.seed,
                             flags.threads, planned_frames, flags.out, physics.imu, flags.uptime_s, &stop_requested},
                            [&bar](int done) { bar.update(done); });
  if (frames == planned_frames) {
    std::printf("recorded %d frames of %s (%s) to %s: capture.pcap, metadata.json, poses.tum%s%s\n", frames,
                profile.name.c_str(), metadata.config_params.value("lidar_mode", "").c_str(), flags.out.c_str(),
                motion.poses->constant() ? "" : ", column_poses.tum",
                frames < flags.frames ? "; the trajectory ended there (--trajectory-end stop)" : "");
    return 0;
  }
  std::fprintf(stderr, "\nrecord: interrupted after %d of %d frames; %s holds them, every file complete\n", frames,
               planned_frames, flags.out.c_str());
  return 130;  // the shell's code for an interrupted command (128 + SIGINT)
}

void setup_record(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<RecordFlags>();
  CLI::App* sub = app.add_subcommand("record", "Render a capture offline: DIR/capture.pcap, metadata.json, poses.tum");
  sub->add_option("--profile", flags->profile,
                  "sensor profile name (e.g. os1-64) or .json path, or a unit's metadata .json (a twin of that unit: "
                  "its mode, udp profile and columns per packet unless given)");
  sub->add_option("--scene", flags->scene, "glTF scene (.glb/.gltf)")->required()->check(CLI::ExistingFile);
  auto* trajectory = sub->add_option("--trajectory", flags->trajectory, "TUM trajectory (see --trajectory-end)")
                         ->check(CLI::ExistingFile);
  sub->add_option("--pose", flags->pose, "a fixed pose \"x y z qx qy qz qw\" (world frame, Z up)")
      ->excludes(trajectory);
  sub->add_option("--trajectory-end", flags->trajectory_end,
                  "past the trajectory's last pose: hold it, loop, or stop the capture there (default: loop a "
                  "trajectory that closes, hold one that does not, as serve does)")
      ->check(CLI::IsMember({"hold", "loop", "stop"}))
      ->excludes("--pose");
  auto* mode = sub->add_option("--mode", flags->mode, "lidar_mode, one of the profile's")
                   ->check(lidar_mode_validator())
                   ->capture_default_str();
  auto* udp_profile = sub->add_option("--udp-profile", flags->udp_profile, "udp_profile_lidar")
                          ->check(udp_profile_validator())
                          ->capture_default_str();
  sub->add_option("--frames", flags->frames, "frames to record")
      ->check(CLI::Range(1, 10'000'000))
      ->capture_default_str();
  sub->add_option("--seed", flags->seed, "noise seed (also sets initialization_id)")->capture_default_str();
  sub->add_option("--out", flags->out, "output directory (created)")->required();
  sub->add_option("--threads", flags->threads, "render threads (0 = all cores)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  auto* columns = sub->add_option("--columns-per-packet", flags->columns_per_packet, "columns per lidar packet")
                      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}))
                      ->capture_default_str();
  sub->add_option("--uptime-s", flags->uptime_s,
                  "the sensor's time since power-on at frame 0: where its timestamps start (TIME_FROM_INTERNAL_OSC)")
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  add_ideal_flag(*sub, flags->ideal);
  sub->add_option("--rig", flags->rig,
                  "a rig file (docs/rig.md): a capture per sensor in OUT/<name>/, each from its mounting on the "
                  "vehicle that --trajectory or --pose moves, with its own profile, mode, seed and serial")
      ->excludes("--profile");
  sub->callback([&run, flags, mode, udp_profile, columns] {
    flags->mode_given = mode->count() > 0;
    flags->udp_profile_given = udp_profile->count() > 0;
    flags->columns_given = columns->count() > 0;
    run = [flags] { return run_record(*flags); };
  });
}

const RegisterCommand registered_record("record", setup_record);

}  // namespace
}  // namespace lidartwin::cli
