// The older "cmd" config API: FW < 3.1 clients and every SDK <= 0.15 (protocol doc 2.2, 2.3).
// The SDK compares some bodies byte for byte (SensorHttpImp::execute), hence the exact strings.
#include "http_api/api_util.h"
#include "http_api/routes.h"

namespace lidartwin {
namespace {

// `args` split at its first space: curl sends "key+value", and "+" decodes to " ".
std::pair<std::string, std::string> split_args(const ApiRequest& request) {
  const auto args = query_value(request, "args");
  if (!args || args->empty()) throw HttpError(400, "query parameter args: missing");
  const auto space = args->find(' ');
  if (space == std::string::npos) return {*args, ""};
  return {args->substr(0, space), args->substr(space + 1)};
}

// args=active | staged, optionally followed by one key ("active lidar_mode").
ApiResponse get_config_param(Sensor& sensor, const ApiRequest& request) {
  const auto [which, key] = split_args(request);
  if (which != "active" && which != "staged") {
    throw HttpError(400, "query parameter args: must be \"active\" or \"staged\", got \"" + which + "\"");
  }
  const auto config = which == "active" ? sensor.active_config() : sensor.staged_config();
  if (key.empty()) return json_response(config);
  if (!config.contains(key)) throw HttpError(400, "args: no config key \"" + key + "\"");
  return json_response(config[key]);
}

// args=.+<JSON object> sets many keys ("." = the whole object); args=<key>+<value> sets one, the
// value as JSON or else as a plain string.
ApiResponse set_config_param(Sensor& sensor, const ApiRequest& request) {
  const auto [key, value] = split_args(request);
  nlohmann::json partial;
  if (key == ".") {
    partial = parse_json(value, "set_config_param args value");
  } else {
    const auto parsed = nlohmann::json::parse(value, nullptr, false);
    partial = {{key, parsed.is_discarded() ? nlohmann::json(value) : parsed}};
  }
  sensor.write_staged(partial, request.peer_ip, "set_config_param args");
  return json_response("set_config_param");
}

ApiResponse set_udp_dest_auto(Sensor& sensor, const ApiRequest& request) {
  sensor.write_staged({{"udp_dest", "@auto"}}, request.peer_ip, "set_udp_dest_auto");
  return json_response(nlohmann::json::object());
}

ApiResponse reinitialize(Sensor& sensor, const ApiRequest&) {
  sensor.reinit();
  return json_response(nlohmann::json::object());
}

ApiResponse save_config_params(Sensor& sensor, const ApiRequest&) {
  sensor.persist();
  return json_response(nlohmann::json::object());
}

}  // namespace

std::vector<Route> cmd_routes() {
  return {
      {"GET", "sensor/cmd/get_config_param", false, get_config_param},
      {"GET", "sensor/cmd/set_config_param", false, set_config_param},
      {"GET", "sensor/cmd/set_udp_dest_auto", false, set_udp_dest_auto},
      {"GET", "sensor/cmd/reinitialize", false, reinitialize},
      {"GET", "sensor/cmd/save_config_params", false, save_config_params},
  };
}

}  // namespace lidartwin
