// The REST config API (FW >= 3.1; protocol doc 2.3, 2.4 (a), (d), 2.7).
#include "http_api/api_util.h"
#include "http_api/routes.h"

namespace lidartwin {
namespace {

// ?staging=true -> staged, otherwise active (SDK >= 0.16 uses no query for active).
ApiResponse get_config(Sensor& sensor, const ApiRequest& request) {
  const bool staging = query_flag(request, "staging", false);
  return json_response(staging ? sensor.staged_config() : sensor.active_config());
}

// The body always merges into staged; reinit then copies staged to active, persist saves active.
// reinit defaults to true unless staging=true: the FW manual says a plain POST applies the
// parameters (protocol doc 2.7); the SDK always passes reinit explicitly, and its udp_dest probe
// `reinit=False&persist=False` (no staging) only writes staged.
ApiResponse post_config(Sensor& sensor, const ApiRequest& request) {
  // All parameters are read before anything changes, so a bad one changes nothing.
  const bool staging = query_flag(request, "staging", false);
  const bool reinit = query_flag(request, "reinit", !staging);
  const bool persist = query_flag(request, "persist", false);
  const auto body = parse_json_body(request, nlohmann::json::object());
  if (!body.is_object() || !body.empty()) sensor.write_staged(body, request.peer_ip, "POST sensor/config");
  if (reinit) sensor.reinit();
  if (persist) sensor.persist();
  return json_response(reinit ? sensor.active_config() : sensor.staged_config());
}

}  // namespace

std::vector<Route> config_routes() {
  return {
      {"GET", "sensor/config", false, get_config},
      {"POST", "sensor/config", false, post_config},
  };
}

}  // namespace lidartwin
