// Routing: normalize the path, find the endpoint, turn every failure into a 4xx/5xx answer.
#include "lidartwin/http_api/request_handler.h"

#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <optional>

#include "http_api/api_util.h"
#include "http_api/routes.h"
#include "lidartwin/error.h"

namespace lidartwin {
namespace {

constexpr std::string_view kApiPrefix = "/api/v1/";

const std::vector<Route>& all_routes() {
  static const std::vector<Route> routes = [] {
    std::vector<Route> all;
    for (auto part : {metadata_routes(), config_routes(), cmd_routes(), user_data_routes(), misc_routes()}) {
      all.insert(all.end(), part.begin(), part.end());
    }
    return all;
  }();
  return routes;
}

// "/api/v1/sensor/config/" -> "sensor/config"; nullopt outside the API.
std::optional<std::string_view> resource_of(std::string_view path) {
  if (!path.starts_with(kApiPrefix)) return std::nullopt;
  path.remove_prefix(kApiPrefix.size());
  while (path.ends_with('/')) path.remove_suffix(1);
  return path;
}

bool matches(const Route& route, std::string_view resource) {
  if (!route.prefix) return resource == route.path;
  return resource.size() > route.path.size() + 1 && resource.starts_with(route.path) &&
         resource[route.path.size()] == '/';
}

ApiResponse dispatch(Sensor& sensor, const ApiRequest& request) {
  const std::string path = origin_form_path(request.path);
  const auto resource = resource_of(path);
  if (!resource) {
    throw HttpError(404, "unknown endpoint " + path + ": the sensor API is below /api/v1/");
  }
  // HEAD is GET without the body (cpp-httplib drops the body).
  const std::string method = request.method == "HEAD" ? "GET" : request.method;
  std::vector<std::string_view> allowed;
  for (const Route& route : all_routes()) {
    if (!matches(route, *resource)) continue;
    if (route.method == "*" || route.method == method) return route.endpoint(sensor, request);
    allowed.push_back(route.method);
  }
  if (allowed.empty()) throw HttpError(404, "unknown endpoint " + path);
  const std::string allowed_list = fmt::format("{}", fmt::join(allowed, ", "));
  auto response =
      error_response(405, "method " + request.method + " is not allowed on " + path + "; allowed: " + allowed_list);
  response.headers.emplace_back("Allow", allowed_list);
  return response;
}

}  // namespace

std::string origin_form_path(const std::string& path) {
  // Absolute form "http://host[:port]/path" arrives through an HTTP proxy (protocol doc 2.1);
  // cpp-httplib keeps it whole in Request::path.
  if (path.empty() || path.front() == '/') return path;
  const auto scheme_end = path.find("://");
  if (scheme_end == std::string::npos) return path;
  const auto path_start = path.find('/', scheme_end + 3);
  return path_start == std::string::npos ? "/" : path.substr(path_start);
}

std::string route_tail(const ApiRequest& request, std::string_view route_path) {
  // Only called for a matched prefix route: the path is /api/v1/<route_path>/<tail>.
  const std::string path = origin_form_path(request.path);
  std::string_view rest = resource_of(path).value_or("");
  rest.remove_prefix(std::min(rest.size(), route_path.size() + 1));
  return std::string(rest);
}

ApiResponse RequestHandler::handle(const ApiRequest& request) const {
  try {
    if (extension_ && origin_form_path(request.path).starts_with(kExtensionPrefix)) return extension_(request);
    return dispatch(sensor_, request);
  } catch (const HttpError& e) {
    return error_response(e.status(), e.what());
  } catch (const InputError& e) {
    return error_response(400, e.what());
  } catch (const nlohmann::json::exception& e) {
    // A JSON type error that escaped validation: the input was wrong, not the server.
    return error_response(400, std::string("bad value: ") + e.what());
  } catch (const std::exception& e) {
    spdlog::error("HTTP{} {} {}: {}", log_tag_, request.method, request.path, e.what());
    return error_response(500, std::string("internal error: ") + e.what());
  }
}

}  // namespace lidartwin
