#pragma once
// What `lidartwin serve` loads before it starts: built-in defaults resolved against the source
// tree, files checked with messages that name the flag.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <optional>

#include <asio/ip/udp.hpp>

#include "cli/unit_twin.h"
#include "lidartwin/pose/live_poses.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/sensor/sensor.h"

namespace lidartwin::cli {

struct ServeFlags {
  std::string profile = "os1-64";
  std::string scene;                    // empty: scenes/plant.glb
  std::string trajectory;               // empty: scenes/plant_inspection.tum with the default scene
  std::string pose;                     // "x y z qx qy qz qw": a sensor standing still
  std::string trajectory_end;           // hold, loop, stop; empty: loop if it closes, else hold
  std::string motion_start = "daemon";  // or "configured": when a client first configures the sensor
  std::string address = "127.0.0.1";
  std::string serial_number;  // empty: 122201 + six digits from the address
  int http_port = 80;
  uint64_t seed = 0;
  bool ideal = false;  // no noise (cli/sensor_physics.h), as record --ideal
  std::string record_dir;
  std::string lidar_mode;   // empty: the sensor's default (1024x10) or the state file's
  std::string udp_profile;  // likewise
  std::string state_file;
  int threads = 0;
  int spin_us = 100;
  int coalesce_us = 2000;
  std::string contention = "auto";  // always, never: whether the host counts as contended
  std::string log_level = "info";
  // Live poses (docs/live-poses.md).
  bool live_poses = false;  // poses arrive over HTTP (and UDP with pose_udp)
  std::string pose_udp;     // "[ADDR:]PORT": also listen for UDP pose messages (implies live_poses)
  std::string pose_clock = "sender";
  double pose_extrapolate_ms = 100.0;
  std::string pose_timeout = "invalid";
  double cast_ahead_ms = 5.0;  // with live poses: how long before a packet is due it is first cast
  std::string mount;           // vehicle_from_sensor "x y z qx qy qz qw"
  bool per_column_poses = true;
  bool lock_step = false;           // the simulator owns time: pose times drive the sensor's clock
  bool stamp_pose_clock = false;    // stamped on the poses' clock, paced on the host's
  std::vector<std::string> faults;  // --fault SPEC, each a comma-separated list (docs/fault-injection.md)
  std::string rig;                  // --rig FILE: the sensors of a rig (docs/rig.md)
};

// An existing file for a flag: as given (relative to the working directory), else relative to the
// source tree. Throws InputError naming the flag, the value and where it looked.
std::filesystem::path find_input(const std::string& flag, const std::string& value);

std::filesystem::path scene_path(const ServeFlags& flags);
// --pose, else --trajectory, else the default scene's inspection flight, else the identity pose.
Trajectory load_trajectory(const ServeFlags& flags);
bool live(const ServeFlags& flags);
LivePoseOptions live_pose_options(const ServeFlags& flags);  // throws InputError naming the flag
// --pose-udp as an endpoint ("9000" listens on --address); nullopt without the flag.
std::optional<asio::ip::udp::endpoint> pose_udp_endpoint(const ServeFlags& flags);
Pose mounting(const ServeFlags& flags);  // --mount, identity without it

// --address as 4 bytes; throws InputError naming the flag unless it is an IPv4 literal.
std::array<uint8_t, 4> parse_address(const std::string& address);

// Who this virtual sensor is: the profile's product and beams; a serial number that differs per
// address, so sensors side by side are told apart by clients (prod_sn in every packet, 4.3).
// A twin of a unit has the unit's serial and firmware. --serial-number, when given, replaces
// either serial (containers all bind 0.0.0.0).
SensorIdentity make_identity(const SensorChoice& sensor, const std::array<uint8_t, 4>& address,
                             const std::string& serial_number = "");
// Config keys set over the saved/default config: a twin's start config (the unit's mode, profile
// and columns per packet) unless a saved state file exists, then the flags.
nlohmann::json config_overrides(const ServeFlags& flags, const std::optional<Metadata>& unit = std::nullopt);

}  // namespace lidartwin::cli
