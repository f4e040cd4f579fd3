#include "cli/serve_inputs.h"

#include <charconv>
#include <cstdlib>

#include <spdlog/spdlog.h>
#include <asio/ip/address_v4.hpp>

#include "lidartwin/error.h"

namespace lidartwin::cli {

namespace {
constexpr const char* kDefaultScene = "scenes/plant.glb";
constexpr const char* kDefaultTrajectory = "scenes/plant_inspection.tum";
}  // namespace

std::filesystem::path find_input(const std::string& flag, const std::string& value) {
  const std::filesystem::path given(value);
  if (std::filesystem::is_regular_file(given)) return given;
  const std::filesystem::path in_source = source_dir() / given;
  if (given.is_relative() && std::filesystem::is_regular_file(in_source)) return in_source;
  std::string message = flag + " " + value + ": no such file";
  if (given.is_relative()) message += " (looked in the working directory and in " + source_dir().string() + ")";
  throw InputError(message + "; set LIDARTWIN_SOURCE_DIR to the lidartwin source tree, or pass a path");
}

std::filesystem::path scene_path(const ServeFlags& flags) {
  return find_input("--scene", flags.scene.empty() ? kDefaultScene : flags.scene);
}

Trajectory load_trajectory(const ServeFlags& flags) {
  if (!flags.pose.empty()) {
    try {
      return Trajectory::constant(parse_pose(flags.pose));
    } catch (const InputError& e) {
      throw InputError(std::string("--pose: ") + e.what());
    }
  }
  if (!flags.trajectory.empty()) return Trajectory::load_tum(find_input("--trajectory", flags.trajectory));
  if (flags.scene.empty()) return Trajectory::load_tum(find_input("--trajectory", kDefaultTrajectory));
  spdlog::warn("serve: no --trajectory or --pose for scene {}: the sensor stands still at the world origin",
               flags.scene);
  return Trajectory::constant(Pose{});
}

bool live(const ServeFlags& flags) {
  return flags.live_poses || !flags.pose_udp.empty() || flags.lock_step || flags.stamp_pose_clock;
}

LivePoseOptions live_pose_options(const ServeFlags& flags) {
  LivePoseOptions options;
  const auto clock = parse_pose_clock(flags.pose_clock);
  if (!clock) throw InputError("--pose-clock " + flags.pose_clock + ": must be sender, monotonic, realtime or tai");
  const auto timeout = parse_pose_timeout(flags.pose_timeout);
  if (!timeout) throw InputError("--pose-timeout " + flags.pose_timeout + ": must be hold, invalid or standby");
  options.clock = flags.lock_step ? PoseClock::kSimulation : *clock;
  options.timeout = *timeout;
  options.max_extrapolation_s = flags.pose_extrapolate_ms * 1e-3;
  // A packet cast cast-ahead before it is due needs poses that far past the newest one (plus the
  // time between poses): with less extrapolation every packet would lack a pose.
  if (!flags.lock_step && options.timeout != PoseTimeout::kHold && flags.cast_ahead_ms >= flags.pose_extrapolate_ms) {
    throw InputError("--cast-ahead-ms " + fmt::format("{}", flags.cast_ahead_ms) +
                     ": must be less than --pose-extrapolate-ms (" + fmt::format("{}", flags.pose_extrapolate_ms) +
                     "): columns are cast that long before the newest pose can reach them");
  }
  return options;
}

std::optional<asio::ip::udp::endpoint> pose_udp_endpoint(const ServeFlags& flags) {
  if (flags.pose_udp.empty()) return std::nullopt;
  const std::string& value = flags.pose_udp;
  const auto colon = value.rfind(':');
  const std::string host = colon == std::string::npos ? flags.address : value.substr(0, colon);
  const std::string port_text = colon == std::string::npos ? value : value.substr(colon + 1);
  const std::string usage = "--pose-udp " + value + ": ";
  int port = -1;
  const auto [end, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (ec != std::errc() || end != port_text.data() + port_text.size() || port < 0 || port > 65535) {
    throw InputError(usage + "the port must be a number 0-65535 (\"9000\" or \"0.0.0.0:9000\")");
  }
  asio::error_code error;
  const auto address = asio::ip::make_address_v4(host, error);
  if (error) throw InputError(usage + "\"" + host + "\" is not an IPv4 address");
  return asio::ip::udp::endpoint(address, static_cast<uint16_t>(port));
}

Pose mounting(const ServeFlags& flags) {
  if (flags.mount.empty()) return {};
  try {
    return parse_pose(flags.mount);
  } catch (const InputError& e) {
    throw InputError(std::string("--mount: ") + e.what());
  }
}

std::array<uint8_t, 4> parse_address(const std::string& address) {
  asio::error_code error;
  const auto parsed = asio::ip::make_address_v4(address, error);
  if (error) throw InputError("--address " + address + ": not an IPv4 address (e.g. 127.0.0.2)");
  return parsed.to_bytes();
}

SensorIdentity make_identity(const SensorChoice& sensor, const std::array<uint8_t, 4>& address,
                             const std::string& serial_number) {
  const SensorProfile& profile = sensor.profile;
  SensorIdentity identity;
  identity.prod_line = profile.prod_line;
  identity.prod_pn = profile.prod_pn;
  identity.beams = profile.beams;
  identity.limits.lidar_modes = profile.lidar_modes;
  // 12 digits like a real serial; the last six from the address's last two bytes.
  const unsigned suffix = static_cast<unsigned>(address[2]) * 256u + address[3];
  identity.prod_sn = "122201" + fmt::format("{:06}", suffix);
  if (sensor.unit) {
    // The unit's firmware as it reports it: clients choose their API by it (protocol doc 2.2), as
    // they would talking to the unit.
    const SensorInfo& unit = sensor.unit->sensor_info;
    if (!unit.prod_sn.empty()) identity.prod_sn = unit.prod_sn;
    if (!unit.image_rev.empty()) identity.image_rev = unit.image_rev;
    if (!unit.build_rev.empty()) identity.build_rev = unit.build_rev;
    if (!unit.build_date.empty()) identity.build_date = unit.build_date;
  }
  if (!serial_number.empty()) identity.prod_sn = serial_number;
  return identity;
}

nlohmann::json config_overrides(const ServeFlags& flags, const std::optional<Metadata>& unit) {
  nlohmann::json overrides = nlohmann::json::object();
  // A saved config is the user's later choice; the unit's file is where the twin starts without one.
  const bool saved = !flags.state_file.empty() && std::filesystem::exists(flags.state_file);
  if (unit && !saved) overrides = unit_start_config(*unit);
  if (!flags.lidar_mode.empty()) overrides["lidar_mode"] = flags.lidar_mode;
  if (!flags.udp_profile.empty()) overrides["udp_profile_lidar"] = flags.udp_profile;
  return overrides;
}

}  // namespace lidartwin::cli
