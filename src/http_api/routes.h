#pragma once
// The endpoint table (protocol doc 2.3), one part per file: metadata, config, cmd, user data, misc.
#include <string>
#include <string_view>
#include <vector>

#include "lidartwin/http_api/request_handler.h"

namespace lidartwin {

using Endpoint = ApiResponse (*)(Sensor& sensor, const ApiRequest& request);

struct Route {
  std::string_view method;  // "GET", "POST", "PUT", "DELETE"; "*" = any
  std::string_view path;    // below /api/v1/, without leading or trailing "/"
  bool prefix;              // true: `path` + "/" + anything (e.g. a metadata section name)
  Endpoint endpoint;
};

std::vector<Route> metadata_routes();
std::vector<Route> config_routes();
std::vector<Route> cmd_routes();
std::vector<Route> user_data_routes();
std::vector<Route> misc_routes();

// The part of the path after the route's prefix ("sensor/metadata/x" -> "x").
std::string route_tail(const ApiRequest& request, std::string_view route_path);

}  // namespace lidartwin
