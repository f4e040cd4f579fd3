// Metadata and firmware endpoints (protocol doc 2.3, 2.5, 3.1).
#include <string>
#include <vector>

#include <fmt/ranges.h>

#include "http_api/api_util.h"
#include "http_api/routes.h"

namespace lidartwin {
namespace {

// Polled every second while INITIALIZING and used for FW detection (protocol doc 2.2, 2.4 (b)).
ApiResponse get_sensor_info(Sensor& sensor, const ApiRequest&) { return json_response(sensor.sensor_info()); }

// All 7 sections + imu_data_format (protocol doc 1.7, 3.1).
ApiResponse get_metadata(Sensor& sensor, const ApiRequest&) {
  sensor.metadata_read();
  return {200, sensor.metadata_text(), {}};
}

// Any section by name, as the FW and the SDK's replay server do (protocol doc 2.3).
ApiResponse get_metadata_section(Sensor& sensor, const ApiRequest& request) {
  const std::string name = route_tail(request, "sensor/metadata");
  if (auto section = sensor.metadata_section(name)) return json_response(*section);
  // A plain loop, not std::views::keys: clang 14 (the fuzz build's) cannot compile libstdc++ 12's
  // views over a std::map.
  const nlohmann::json document = sensor.metadata();
  std::vector<std::string> sections;
  for (const auto& [key, unused] : document.items()) sections.push_back(key);
  throw HttpError(404, fmt::format("no metadata section \"{}\"; sections: {}", name, fmt::join(sections, ", ")));
}

// SDK <= 0.15 detects the FW from this (protocol doc 2.2).
ApiResponse get_firmware(Sensor& sensor, const ApiRequest&) {
  return json_response({{"fw", sensor.identity().image_rev}});
}

}  // namespace

std::vector<Route> metadata_routes() {
  return {
      {"GET", "sensor/metadata/sensor_info", false, get_sensor_info},
      {"GET", "sensor/metadata", false, get_metadata},
      {"GET", "sensor/metadata", true, get_metadata_section},
      {"GET", "system/firmware", false, get_firmware},
  };
}

}  // namespace lidartwin
