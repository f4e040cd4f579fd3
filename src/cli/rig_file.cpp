#include "cli/rig_file.h"

#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include "cli/format_validators.h"
#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"
#include "lidartwin/pose/pose.h"

namespace lidartwin::cli {
namespace {

using json_reader::Location;
using json_reader::ObjectReader;

constexpr size_t kMaxSensors = 64;

// A CLI11 validator's verdict on a value read from the file.
void check(const CLI::Validator& validator, const std::string& value, const Location& at) {
  std::string copy = value;
  const std::string problem = validator(copy);
  if (!problem.empty()) at.fail(problem);
}

// A path as the file gives it, relative to the file's directory.
std::string relative_to(const std::filesystem::path& dir, const std::string& value) {
  const std::filesystem::path path(value);
  return path.is_absolute() ? value : (dir / path).lexically_normal().string();
}

// A profile by name stays a name; a .json is a file next to the rig file (else as given).
std::string profile_of(const std::filesystem::path& dir, const std::string& value) {
  if (!value.ends_with(".json")) return value;
  const std::string beside = relative_to(dir, value);
  return std::filesystem::exists(beside) ? beside : value;
}

// "x y z qx qy qz qw" from an array of 7 numbers, as --mount takes it.
std::string mount_of(const nlohmann::json& value, const Location& at) {
  const std::vector<double> v = json_reader::read_numbers(value, at, {-1e6, 1e6}, 7);
  std::ostringstream text;
  text.precision(17);
  for (size_t i = 0; i < v.size(); ++i) text << (i ? " " : "") << v[i];
  try {
    parse_pose(text.str());
  } catch (const InputError& e) {
    at.fail(e.what());
  }
  return text.str();
}

}  // namespace

const std::vector<std::string>& per_sensor_flags() {
  static const std::vector<std::string> flags{"--profile",    "--address",    "--serial-number",
                                              "--record",     "--lidar-mode", "--udp-profile",
                                              "--state-file", "--mount",      "--fault"};
  return flags;
}

std::vector<RigSensor> load_rig(const std::filesystem::path& file, const ServeFlags& command_line) {
  std::ifstream in(file);
  if (!in) throw InputError(fmt::format("--rig {}: cannot be read", file.string()));
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(fmt::format("--rig {}: not JSON ({})", file.string(), e.what()));
  }
  const std::filesystem::path dir = file.parent_path();
  const Location root{file.string(), ""};
  const ObjectReader rig(document, root, {"sensors", "description"});
  const nlohmann::json& list = rig.at("sensors", "an array of sensors");
  if (!list.is_array() || list.empty() || list.size() > kMaxSensors) {
    rig.child("sensors").fail_expected(fmt::format("an array of 1 to {} sensors", kMaxSensors), list);
  }
  std::vector<RigSensor> sensors;
  std::map<std::pair<std::string, int>, std::string> endpoints;  // (address, HTTP port) -> sensor
  std::map<std::string, std::string> names, serials;
  for (size_t i = 0; i < list.size(); ++i) {
    const Location at = rig.child("sensors").child(i);
    RigSensor sensor;
    if (!list[i].is_object()) at.fail_expected("a sensor (an object with name, profile, address...)", list[i]);
    const auto name = list[i].find("name");
    if (name == list[i].end()) at.child("name").fail("missing (expected the sensor's name, e.g. \"roof\")");
    sensor.name = json_reader::read_string(*name, at.child("name"));
    // Messages name the sensor as well as its index: "rig.json: /sensors/1 (left)/address: ...".
    const Location named{at.source, at.pointer + " (" + sensor.name + ")"};
    const ObjectReader entry(list[i], named,
                             {"name", "profile", "address", "serial_number", "http_port", "mount", "lidar_mode",
                              "udp_profile", "state_file", "record", "seed", "fault"},
                             json_reader::UnknownKeys::kReject, "a rig's sensor");
    const auto child = [&](std::string_view key) { return named.child(key); };
    if (sensor.name.empty() || !names.emplace(sensor.name, at.pointer).second) {
      child("name").fail("must be a name no other sensor of the rig has");
    }
    ServeFlags& flags = sensor.flags;
    flags = command_line;
    flags.profile = profile_of(
        dir, json_reader::read_string(entry.at("profile", "a profile name, a profile .json or a unit's metadata"),
                                      child("profile")));
    flags.address = json_reader::read_string(entry.at("address", "the sensor's IPv4 address"), child("address"));
    try {
      parse_address(flags.address);
    } catch (const InputError&) {
      child("address").fail("must be an IPv4 address, e.g. \"127.0.0.2\"");
    }
    if (const auto* v = entry.find("http_port")) {
      flags.http_port = static_cast<int>(json_reader::read_integer(*v, child("http_port"), 0, 65535));
    }
    if (flags.http_port != 0 && !endpoints.emplace(std::pair{flags.address, flags.http_port}, sensor.name).second) {
      child("address").fail(fmt::format("{}:{} is already sensor \"{}\"'s; give each sensor its own address",
                                        flags.address, flags.http_port,
                                        endpoints.at({flags.address, flags.http_port})));
    }
    flags.serial_number.clear();
    if (const auto* v = entry.find("serial_number")) {
      flags.serial_number = json_reader::read_string(*v, child("serial_number"));
      check(serial_number_validator(), flags.serial_number, child("serial_number"));
      if (!serials.emplace(flags.serial_number, sensor.name).second) {
        child("serial_number").fail(fmt::format("is already sensor \"{}\"'s", serials.at(flags.serial_number)));
      }
    }
    flags.mount = entry.find("mount") ? mount_of(*entry.find("mount"), child("mount")) : std::string();
    flags.lidar_mode.clear();
    if (const auto* v = entry.find("lidar_mode")) {
      flags.lidar_mode = json_reader::read_string(*v, child("lidar_mode"));
      check(lidar_mode_validator(), flags.lidar_mode, child("lidar_mode"));
    }
    flags.udp_profile.clear();
    if (const auto* v = entry.find("udp_profile")) {
      flags.udp_profile = json_reader::read_string(*v, child("udp_profile"));
      check(udp_profile_validator(), flags.udp_profile, child("udp_profile"));
    }
    flags.state_file = entry.find("state_file")
                           ? relative_to(dir, json_reader::read_string(*entry.find("state_file"), child("state_file")))
                           : std::string();
    flags.record_dir = entry.find("record")
                           ? relative_to(dir, json_reader::read_string(*entry.find("record"), child("record")))
                           : std::string();
    // Each sensor draws its own noise: the command line's seed plus the sensor's index, unless given.
    flags.seed =
        entry.find("seed")
            ? static_cast<uint64_t>(json_reader::read_integer(*entry.find("seed"), child("seed"), 0, int64_t{1} << 53))
            : command_line.seed + i;
    flags.faults.clear();
    if (const auto* v = entry.find("fault")) flags.faults.push_back(json_reader::read_string(*v, child("fault")));
    sensors.push_back(std::move(sensor));
  }
  return sensors;
}

}  // namespace lidartwin::cli
