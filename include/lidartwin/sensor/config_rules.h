#pragma once
// What a sensor config may contain: the type and range of every key the SDK knows (protocol doc
// 2.6), checked on the config as a whole before it replaces the staged one (STYLE.md "Errors at
// the boundary": never half-apply). Unknown keys are allowed and kept: the SDK sends them back.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/json/json_reader.h"

namespace lidartwin {

// What this sensor supports beyond the protocol's own enums. Empty = anything the packet module
// can parse.
struct ConfigLimits {
  std::vector<std::string> lidar_modes;         // e.g. {"512x10", "1024x10", "2048x10"}
  std::vector<std::string> udp_profiles_lidar;  // e.g. {"LEGACY", "RNG19_RFL8_SIG16_NIR16"}
};

// Every problem of `config`, which sits at `at` (a request body: {"POST sensor/config", ""}; a
// state file: {"state.json", "/config"}), one message per bad key in json_reader's form:
// "<source>: /<key>: must be <expected>, got <value>". Empty when the config is valid. udp_dest
// must already be resolved to an IPv4 literal (see resolve_udp_dest).
std::vector<std::string> config_errors(const nlohmann::json& config, const ConfigLimits& limits,
                                       const json_reader::Location& at);

// Throws InputError(<config_errors joined by "; ">) unless config_errors is empty.
void validate_config(const nlohmann::json& config, const ConfigLimits& limits, const json_reader::Location& at);

// The value of udp_dest / udp_dest_zm / udp_ip as written by a client, resolved at write time
// (protocol doc 1.6, 2.7): "@auto" becomes the HTTP peer's IPv4 address, a host name its first
// IPv4 address, an IPv4 literal stays as it is. An IPv4-mapped IPv6 peer ("::ffff:a.b.c.d") maps to
// a.b.c.d and "::1" to 127.0.0.1, because the streamer sends IPv4 only. Throws InputError naming
// `at` (the key's location) when the value cannot become an IPv4 address (empty `peer_ip` = no
// HTTP peer).
std::string resolve_udp_dest(const nlohmann::json& value, const json_reader::Location& at, const std::string& peer_ip);

}  // namespace lidartwin
