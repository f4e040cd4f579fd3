#pragma once
// The HTTP API as a pure function: an ApiRequest in, an ApiResponse out, mapped onto Sensor
// operations (protocol doc 2.3). No sockets here, so every endpoint can be tested without a network;
// HttpServer does the I/O with cpp-httplib.
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lidartwin/sensor/sensor.h"

namespace lidartwin {

struct ApiRequest {
  std::string method;  // "GET", "POST", ...
  // The path as received: origin form "/api/v1/..." or, through an HTTP proxy, absolute form
  // "http://host/api/v1/..." (protocol doc 2.1). Already percent-decoded, without the query.
  std::string path;
  std::multimap<std::string, std::string> query;  // decoded; "+" became " "
  std::string body;
  std::string peer_ip;   // the client's address, for "@auto" (protocol doc 2.7)
  std::string local_ip;  // the address the request arrived at
};

struct ApiResponse {
  int status = 200;
  std::string body;                                          // always JSON
  std::vector<std::pair<std::string, std::string>> headers;  // extra headers, e.g. Allow
};

// Thrown by endpoints: answered with `status` and {"error": what()}. (InputError -> 400.)
class HttpError : public std::runtime_error {
 public:
  HttpError(int status, const std::string& message) : std::runtime_error(message), status_(status) {}
  int status() const { return status_; }

 private:
  int status_;
};

// Answers requests below kExtensionPrefix: the daemon's own endpoints, which the sensor state
// machine knows nothing of (live poses). Throws like any endpoint (HttpError, InputError).
using ExtensionEndpoint = std::function<ApiResponse(const ApiRequest& request)>;
inline constexpr std::string_view kExtensionPrefix = "/lidartwin/v1/";

class RequestHandler {
 public:
  // `log_tag` follows "HTTP" in the log line of an unexpected error (log_tag.h).
  explicit RequestHandler(Sensor& sensor, ExtensionEndpoint extension = nullptr, std::string log_tag = {})
      : sensor_(sensor), extension_(std::move(extension)), log_tag_(std::move(log_tag)) {}

  // Never throws: bad input becomes a 4xx naming the problem, anything unexpected a 500.
  ApiResponse handle(const ApiRequest& request) const;

 private:
  Sensor& sensor_;
  ExtensionEndpoint extension_;
  std::string log_tag_;
};

// "http://host:port/api/v1/x" -> "/api/v1/x"; origin-form paths are returned unchanged.
std::string origin_form_path(const std::string& path);

}  // namespace lidartwin
