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

using json_reader::Location;
using nlohmann::json;
// Throws InputError "<source>: /<key>: must be <what>, got <the value>" unless the value is fine.
using Check = std::function<void(const json&, const Location&)>;

// "a", "b", "c" (fmt's debug format quotes each name).
std::string quoted_list(const std::vector<std::string>& names) { return fmt::format("{:?}", fmt::join(names, ", ")); }

// A check from a predicate and what it expects.
Check expecting(std::string what, std::function<bool(const json&)> accepts) {
  return [what = std::move(what), accepts = std::move(accepts)](const json& v, const Location& at) {
    if (!accepts(v)) at.fail_expected(what, v);
  };
}

Check one_of(std::vector<std::string> names) {
  const std::string what = "one of " + quoted_list(names);
  return expecting(what, [names = std::move(names)](const json& v) {
    return v.is_string() && std::find(names.begin(), names.end(), v.get<std::string>()) != names.end();
  });
}

// Integers only: unlike json_reader::read_integer, 7502.0 is refused, as this API always has (the
// SDK writes integers).
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
  return expecting("an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]", [lo, hi](const json& v) {
    const auto i = as_int64(v);
    return i && *i >= lo && *i <= hi;
  });
}

Check integer_in(std::vector<int64_t> allowed) {
  const std::string what = fmt::format("one of {}", fmt::join(allowed, ", "));
  return expecting(what, [allowed = std::move(allowed)](const json& v) {
    const auto i = as_int64(v);
    return i && std::find(allowed.begin(), allowed.end(), *i) != allowed.end();
  });
}

Check boolean() {
  return [](const json& v, const Location& at) { json_reader::read_bool(v, at); };
}

// nmea_ignore_valid_char, auto_start_flag: the FW uses 0/1, some clients send booleans.
Check zero_or_one() {
  return expecting("0 or 1",
                   [](const json& v) { return v.is_boolean() || (v.is_number_integer() && (v == 0 || v == 1)); });
}

// 2.4 (a): the SDK only accepts these and writes 1, 2, 3 back as integers.
Check signal_multiplier() {
  return expecting("one of 0.25, 0.5, 1, 2, 3", [](const json& v) {
    if (!v.is_number()) return false;
    const double m = v.get<double>();
    return m == 0.25 || m == 0.5 || m == 1 || m == 2 || m == 3;
  });
}

// udp_dest must be set (an empty one forces the lidar profile to OFF in the SDK, protocol doc
// 3.1); udp_dest_zm may be empty (= no zone packets).
Check ipv4_address(bool allow_empty) {
  return expecting(std::string("an IPv4 address, a host name or \"@auto\"") + (allow_empty ? " or \"\"" : ""),
                   [allow_empty](const json& v) {
                     return v.is_string() &&
                            ((allow_empty && v.get<std::string>().empty()) || parse_ipv4(v.get<std::string>()));
                   });
}

// [start, end] in millidegrees (protocol doc 6.4).
Check azimuth_window() {
  return expecting("[start, end] with integers in [0, 360000]", [](const json& v) {
    return v.is_array() && v.size() == 2 && std::all_of(v.begin(), v.end(), [](const json& e) {
             const auto i = as_int64(e);
             return i && *i >= 0 && *i <= 360000;
           });
  });
}

// W must be 512/1024/2048/4096 or the SDK throws (protocol doc 2.6); the product narrows it.
Check lidar_mode(const std::vector<std::string>& supported) {
  const std::string what =
      supported.empty() ? "a lidar mode such as \"1024x10\"" : "a lidar mode of this sensor: " + quoted_list(supported);
  return expecting(what, [supported](const json& v) {
    const bool parses = v.is_string() && parse_lidar_mode(v.get<std::string>()).has_value();
    return parses && (supported.empty() ||
                      std::find(supported.begin(), supported.end(), v.get<std::string>()) != supported.end());
  });
}

Check udp_profile_lidar(std::vector<std::string> supported) {
  if (supported.empty()) {
    for (auto name : udp_profile_lidar_names()) supported.emplace_back(name);
  }
  return [check = one_of(supported)](const json& v, const Location& at) {
    if (v.is_string() && !udp_profile_lidar_from_string(v.get<std::string>())) {
      at.fail_expected("a lidar profile lidartwin can send", v);
    }
    check(v, at);
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

// A packet carries whole columns: columns_per_packet must divide W (protocol doc 4.1). Runs after
// both keys passed their own checks.
void check_columns_per_packet(const json& config, const Location& at) {
  if (!config.contains("columns_per_packet") || !config.contains("lidar_mode")) return;
  const auto per_packet = as_int64(config["columns_per_packet"]);
  const auto& mode_text = config["lidar_mode"];
  if (!per_packet || *per_packet <= 0 || !mode_text.is_string()) return;
  const auto mode = parse_lidar_mode(mode_text.get<std::string>());
  if (!mode || mode->columns_per_frame % *per_packet == 0) return;
  at.child("columns_per_packet")
      .fail(std::to_string(*per_packet) + " does not divide the " + std::to_string(mode->columns_per_frame) +
            " columns of lidar_mode " + mode_text.dump());
}

// Runs `check`; its InputError's message joins `errors` instead of propagating, so that one
// answer names every bad key.
template <class F>
void collect(std::vector<std::string>& errors, F&& check) {
  try {
    check();
  } catch (const InputError& e) {
    errors.emplace_back(e.what());
  }
}

}  // namespace

std::vector<std::string> config_errors(const json& config, const ConfigLimits& limits, const Location& at) {
  std::vector<std::string> errors;
  collect(errors, [&] { json_reader::ObjectReader(config, at, {}, json_reader::UnknownKeys::kKeep); });
  if (!errors.empty()) return errors;
  for (auto key : kRequiredKeys) {
    if (!config.contains(key)) errors.push_back(at.child(key).to_string() + ": missing");
  }
  for (const auto& rule : rules(limits)) {
    const auto it = config.find(rule.key);
    if (it != config.end()) collect(errors, [&] { rule.check(*it, at.child(rule.key)); });
  }
  collect(errors, [&] { check_columns_per_packet(config, at); });
  return errors;
}

void validate_config(const json& config, const ConfigLimits& limits, const Location& at) {
  const auto errors = config_errors(config, limits, at);
  if (!errors.empty()) throw InputError(fmt::format("{}", fmt::join(errors, "; ")));
}

}  // namespace lidartwin
