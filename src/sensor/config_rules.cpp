// Type and range of every config key the SDK knows (protocol doc 2.6), as one table of checks.
#include "lidartwin/sensor/config_rules.h"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string_view>

#include <fmt/ranges.h>

#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"
#include "lidartwin/packet/data_format.h"
#include "sensor/ipv4.h"

namespace lidartwin {
namespace {

using nlohmann::json;
// A problem with the value (what was expected), or nullopt when it is fine.
using Check = std::function<std::optional<std::string>(const json&)>;

std::string shown(const json& value) { return json_reader::describe(value); }

// "a", "b", "c" (fmt's debug format quotes each name).
std::string quoted_list(const std::vector<std::string>& names) { return fmt::format("{:?}", fmt::join(names, ", ")); }

std::optional<std::string> expected(const std::string& what, const json& value) {
  return "must be " + what + ", got " + shown(value);
}

Check one_of(std::vector<std::string> names) {
  return [names = std::move(names)](const json& v) -> std::optional<std::string> {
    if (v.is_string() && std::find(names.begin(), names.end(), v.get<std::string>()) != names.end())
      return std::nullopt;
    return expected("one of " + quoted_list(names), v);
  };
}

std::optional<int64_t> as_int64(const json& v) {
  if (v.is_number_unsigned()) {
    const auto u = v.get<uint64_t>();
    if (u > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) return std::nullopt;
    return static_cast<int64_t>(u);
  }
  if (v.is_number_integer()) return v.get<int64_t>();
  return std::nullopt;
}

Check integer(int64_t lo, int64_t hi) {
  return [lo, hi](const json& v) -> std::optional<std::string> {
    const auto i = as_int64(v);
    if (i && *i >= lo && *i <= hi) return std::nullopt;
    return expected("an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]", v);
  };
}

Check integer_in(std::vector<int64_t> allowed) {
  return [allowed = std::move(allowed)](const json& v) -> std::optional<std::string> {
    const auto i = as_int64(v);
    if (i && std::find(allowed.begin(), allowed.end(), *i) != allowed.end()) return std::nullopt;
    return expected(fmt::format("one of {}", fmt::join(allowed, ", ")), v);
  };
}

Check boolean() {
  return [](const json& v) -> std::optional<std::string> {
    return v.is_boolean() ? std::nullopt : expected("true or false", v);
  };
}

// nmea_ignore_valid_char, auto_start_flag: the FW uses 0/1, some clients send booleans.
Check zero_or_one() {
  return [](const json& v) -> std::optional<std::string> {
    if (v.is_boolean() || (v.is_number_integer() && (v == 0 || v == 1))) return std::nullopt;
    return expected("0 or 1", v);
  };
}

// 2.4 (a): the SDK only accepts these and writes 1, 2, 3 back as integers.
Check signal_multiplier() {
  return [](const json& v) -> std::optional<std::string> {
    if (v.is_number()) {
      const double m = v.get<double>();
      if (m == 0.25 || m == 0.5 || m == 1 || m == 2 || m == 3) return std::nullopt;
    }
    return expected("one of 0.25, 0.5, 1, 2, 3", v);
  };
}

// udp_dest must be set (an empty one forces the lidar profile to OFF in the SDK, protocol doc
// 3.1); udp_dest_zm may be empty (= no zone packets).
Check ipv4_address(bool allow_empty) {
  return [allow_empty](const json& v) -> std::optional<std::string> {
    if (v.is_string() && ((allow_empty && v.get<std::string>().empty()) || parse_ipv4(v.get<std::string>())))
      return std::nullopt;
    return expected(std::string("an IPv4 address, a host name or \"@auto\"") + (allow_empty ? " or \"\"" : ""), v);
  };
}

// [start, end] in millidegrees (protocol doc 6.4).
Check azimuth_window() {
  return [](const json& v) -> std::optional<std::string> {
    const bool ok = v.is_array() && v.size() == 2 && std::all_of(v.begin(), v.end(), [](const json& e) {
                      const auto i = as_int64(e);
                      return i && *i >= 0 && *i <= 360000;
                    });
    return ok ? std::nullopt : expected("[start, end] with integers in [0, 360000]", v);
  };
}

// W must be 512/1024/2048/4096 or the SDK throws (protocol doc 2.6); the product narrows it.
Check lidar_mode(const std::vector<std::string>& supported) {
  return [supported](const json& v) -> std::optional<std::string> {
    const bool parses = v.is_string() && parse_lidar_mode(v.get<std::string>()).has_value();
    const bool allowed = parses && (supported.empty() || std::find(supported.begin(), supported.end(),
                                                                   v.get<std::string>()) != supported.end());
    if (allowed) return std::nullopt;
    if (supported.empty()) return expected("a lidar mode such as \"1024x10\"", v);
    return expected("a lidar mode of this sensor: " + quoted_list(supported), v);
  };
}

Check udp_profile_lidar(std::vector<std::string> supported) {
  if (supported.empty()) {
    for (auto name : udp_profile_lidar_names()) supported.emplace_back(name);
  }
  return [check = one_of(supported)](const json& v) -> std::optional<std::string> {
    if (v.is_string() && !udp_profile_lidar_from_string(v.get<std::string>()))
      return expected("a lidar profile lidartwin can send", v);
    return check(v);
  };
}

struct Rule {
  std::string_view key;
  Check check;
};

// Where and how the data goes.
std::vector<Rule> stream_rules(const ConfigLimits& limits) {
  return {
      {"udp_dest", ipv4_address(false)},
      {"udp_dest_zm", ipv4_address(true)},
      {"udp_ip", ipv4_address(false)},  // FW 2.0/2.1 name of udp_dest
      {"udp_port_lidar", integer(0, 65535)},
      {"udp_port_imu", integer(0, 65535)},
      {"udp_port_zm", integer(0, 65535)},
      {"udp_multicast_ttl", integer(0, 255)},
      {"udp_multicast_ttl_zm", integer(0, 255)},
      {"lidar_mode", lidar_mode(limits.lidar_modes)},
      {"operating_mode", one_of({"NORMAL", "STANDBY"})},
      {"auto_start_flag", zero_or_one()},
      {"azimuth_window", azimuth_window()},
      {"lidar_frame_azimuth_offset", integer(0, 360000)},
      {"signal_multiplier", signal_multiplier()},
      {"columns_per_packet", integer_in({1, 2, 4, 8, 16, 32, 64})},
      {"udp_profile_lidar", udp_profile_lidar(limits.udp_profiles_lidar)},
      {"udp_profile_imu", one_of({"LEGACY", "ACCEL32_GYRO32_NMEA", "OFF"})},
      {"header_type", one_of({"STANDARD", "FUSA"})},
      {"imu_packets_per_frame", integer(0, 1000)},
      {"gyro_fsr", one_of({"NORMAL", "EXTENDED"})},
      {"accel_fsr", one_of({"NORMAL", "EXTENDED"})},
      {"return_order", one_of({"STRONGEST_TO_WEAKEST", "FARTHEST_TO_NEAREST", "NEAREST_TO_FARTHEST"})},
      {"min_range_threshold_cm", integer(0, 100000)},
      {"bloom_reduction_optimization", one_of({"BALANCED", "MINIMIZE_FALSE_POSITIVES"})},
  };
}

// Time sources and the sync/NMEA connector.
std::vector<Rule> timing_rules() {
  const std::vector<std::string> polarity{"ACTIVE_HIGH", "ACTIVE_LOW"};
  return {
      {"timestamp_mode", one_of({"TIME_FROM_INTERNAL_OSC", "TIME_FROM_SYNC_PULSE_IN", "TIME_FROM_PTP_1588"})},
      {"multipurpose_io_mode",
       one_of({"OFF", "INPUT_NMEA_UART", "OUTPUT_FROM_INTERNAL_OSC", "OUTPUT_FROM_SYNC_PULSE_IN",
               "OUTPUT_FROM_PTP_1588", "OUTPUT_FROM_ENCODER_ANGLE"})},
      {"nmea_in_polarity", one_of(polarity)},
      {"sync_pulse_in_polarity", one_of(polarity)},
      {"sync_pulse_out_polarity", one_of(polarity)},
      {"nmea_ignore_valid_char", zero_or_one()},
      {"nmea_baud_rate", one_of({"BAUD_9600", "BAUD_115200"})},
      {"nmea_leap_seconds", integer(0, 1000)},
      {"sync_pulse_out_angle", integer(0, 360)},
      {"sync_pulse_out_frequency", integer(1, 1000000)},
      {"sync_pulse_out_pulse_width", integer(0, 1000000)},
      {"phase_lock_enable", boolean()},
      {"phase_lock_offset", integer(0, 360000)},
  };
}

std::vector<Rule> rules(const ConfigLimits& limits) {
  auto all = stream_rules(limits);
  auto timing = timing_rules();
  all.insert(all.end(), timing.begin(), timing.end());
  return all;
}

// Consumers dereference these without checking (protocol doc 3.1), so they must be present.
constexpr std::string_view kRequiredKeys[] = {"udp_dest", "udp_port_lidar", "udp_port_imu", "lidar_mode"};

// A packet carries whole columns: columns_per_packet must divide W (protocol doc 4.1).
std::optional<std::string> columns_per_packet_error(const json& config) {
  if (!config.contains("columns_per_packet") || !config.contains("lidar_mode")) return {};
  const auto& cpp = config["columns_per_packet"];
  const auto& mode_text = config["lidar_mode"];
  const auto per_packet = as_int64(cpp);
  if (!per_packet || *per_packet <= 0 || !mode_text.is_string()) return {};
  const auto mode = parse_lidar_mode(mode_text.get<std::string>());
  if (!mode || mode->columns_per_frame % *per_packet == 0) return {};
  return "columns_per_packet: " + std::to_string(*per_packet) + " does not divide the " +
         std::to_string(mode->columns_per_frame) + " columns of lidar_mode " + mode_text.dump();
}

}  // namespace

std::vector<std::string> config_errors(const json& config, const ConfigLimits& limits) {
  if (!config.is_object()) return {"config must be a JSON object, got " + shown(config)};
  std::vector<std::string> errors;
  for (auto key : kRequiredKeys) {
    if (!config.contains(key)) errors.push_back(std::string(key) + ": missing");
  }
  for (const auto& rule : rules(limits)) {
    const auto it = config.find(rule.key);
    if (it == config.end()) continue;
    if (auto problem = rule.check(*it)) errors.push_back(std::string(rule.key) + ": " + *problem);
  }
  if (auto problem = columns_per_packet_error(config)) errors.push_back(*problem);
  return errors;
}

void validate_config(const json& config, const ConfigLimits& limits, const std::string& source) {
  const auto errors = config_errors(config, limits);
  if (errors.empty()) return;
  std::string message = source + ": ";
  for (size_t i = 0; i < errors.size(); ++i) message += (i ? "; " : "") + errors[i];
  throw InputError(message);
}

}  // namespace lidartwin
