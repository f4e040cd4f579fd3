// libFuzzer: an HTTP request as cpp-httplib hands it to the real RequestHandler, answered by a real
// Sensor (config bodies, the cmd API's query strings, user data, metadata sections). Input layout,
// so that mutations stay on the real endpoints instead of spending themselves on path spelling:
//   byte 0: the method (kMethods[b % n]); byte 1: the endpoint (kEndpoints[b % n]);
//   then up to the first '\n': appended to the endpoint's path, a '?' starting the query string
//   ("k=v&k2=v2", already decoded as cpp-httplib delivers it); the rest: the body.
// Invariants: nothing escapes handle(); every answer is JSON (ApiResponse's contract); bad input is
// a 4xx, never a 500 (a 500 means an exception slipped past validation); a refused request leaves
// the staged and active configs as they were (a config is never half-applied).
// Seeds: tools/fuzz (config bodies from the Ouster sample metadata, cmd and user-data requests).
#include <netdb.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "lidartwin/http_api/request_handler.h"
#include "lidartwin/sensor/sensor.h"

// Host names in udp_dest would otherwise go to the network's DNS server on every run: slow, not
// reproducible, and no business of a fuzzer. This definition replaces libc's (and the sanitizer's
// weak interceptor), so every name is unknown and only IPv4 literals and "@auto" resolve.
extern "C" int getaddrinfo(const char*, const char*, const addrinfo*, addrinfo** result) {
  *result = nullptr;
  return EAI_NONAME;
}

namespace {

constexpr std::array<std::string_view, 6> kMethods = {"GET", "POST", "PUT", "DELETE", "HEAD", "PATCH"};

// Every route of src/http_api/*_endpoints.cpp, plus the paths around them the router must refuse.
constexpr std::array<std::string_view, 24> kEndpoints = {
    "/api/v1/sensor/config",
    "/api/v1/sensor/cmd/set_config_param",
    "/api/v1/sensor/cmd/get_config_param",
    "/api/v1/sensor/cmd/set_udp_dest_auto",
    "/api/v1/sensor/cmd/reinitialize",
    "/api/v1/sensor/cmd/save_config_params",
    "/api/v1/user/data",
    "/api/v1/sensor/metadata",
    "/api/v1/sensor/metadata/",
    "/api/v1/sensor/metadata/sensor_info",
    "/api/v1/system/firmware",
    "/api/v1/sensor/telemetry",
    "/api/v1/time/system",
    "/api/v1/time/sensor",
    "/api/v1/time/ptp",
    "/api/v1/sensor/alerts",
    "/api/v1/system/network",
    "/api/v1/zone_monitor",
    "/api/v1/",
    "/lidartwin/v1/",
    "http://192.0.2.7:8080/api/v1/sensor/config",  // absolute form, through a proxy
    "/",
    "",
    "/api/v1/sensor/cmd/",
};

lidartwin::SensorIdentity fuzz_identity() {
  lidartwin::SensorIdentity identity;
  for (int row = 0; row < 64; ++row) {  // an OS-1-64, the identity's default product
    identity.beams.altitude_deg.push_back(16.6 - 0.52 * row);
    identity.beams.azimuth_deg.push_back(std::array{3.1, 0.9, -1.2, -3.3}[row % 4]);
  }
  identity.beams.lidar_origin_to_beam_origin_mm = 12.163;
  identity.limits.lidar_modes = {"512x10", "1024x10", "2048x10"};
  return identity;
}

// "a=1&b=&c" -> {a: 1, b: "", c: ""}, as cpp-httplib's parse_query_text splits it.
std::multimap<std::string, std::string> parse_query(std::string_view text) {
  std::multimap<std::string, std::string> query;
  while (!text.empty()) {
    const size_t end = std::min(text.find('&'), text.size());
    const std::string_view pair = text.substr(0, end);
    const size_t equals = std::min(pair.find('='), pair.size());
    if (!pair.empty()) {
      query.emplace(pair.substr(0, equals), equals < pair.size() ? pair.substr(equals + 1) : std::string_view());
    }
    text.remove_prefix(std::min(end + 1, text.size()));
  }
  return query;
}

lidartwin::ApiRequest request_of(const uint8_t* data, size_t size) {
  lidartwin::ApiRequest request;
  request.method = kMethods[data[0] % kMethods.size()];
  request.peer_ip = "192.0.2.44";  // "@auto" resolves to it
  request.local_ip = "127.0.0.1";
  const std::string_view rest(reinterpret_cast<const char*>(data + 2), size - 2);
  const size_t line_end = std::min(rest.find('\n'), rest.size());
  const std::string_view target = rest.substr(0, line_end);
  const size_t question = std::min(target.find('?'), target.size());
  request.path = std::string(kEndpoints[data[1] % kEndpoints.size()]) + std::string(target.substr(0, question));
  if (question < target.size()) request.query = parse_query(target.substr(question + 1));
  if (line_end < rest.size()) request.body = rest.substr(line_end + 1);
  return request;
}

[[noreturn]] void violated(const char* what, const lidartwin::ApiRequest& request,
                           const lidartwin::ApiResponse& response) {
  std::fprintf(stderr, "%s: %s %s -> %d %s\n", what, request.method.c_str(), request.path.c_str(), response.status,
               response.body.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const lidartwin::ApiRequest request = request_of(data, size);
  // A fresh sensor per input, so a crash replays from its input alone.
  lidartwin::Sensor sensor(fuzz_identity(), {.config_overrides = {{"udp_dest", "192.0.2.1"}},
                                             .initializing_time = std::chrono::milliseconds(0)});
  const nlohmann::json staged = sensor.staged_config();
  const nlohmann::json active = sensor.active_config();
  const lidartwin::RequestHandler handler(sensor);

  const lidartwin::ApiResponse response = handler.handle(request);

  if (response.status < 200 || response.status >= 500) violated("status outside 2xx-4xx", request, response);
  if (!nlohmann::json::accept(response.body)) violated("body is not JSON", request, response);
  if (response.status >= 400 && (sensor.staged_config() != staged || sensor.active_config() != active)) {
    violated("a refused request changed the config", request, response);
  }
  return 0;
}
