// Fault injection over HTTP (include/lidartwin/rig/fault_api.h).
#include "lidartwin/rig/fault_api.h"

#include <string>

#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin {
namespace {

using nlohmann::json;

// A query parameter as an unsigned integer, or `fallback` when absent.
uint64_t query_number(const ApiRequest& request, const std::string& name, uint64_t fallback, uint64_t max) {
  const auto it = request.query.find(name);
  if (it == request.query.end()) return fallback;
  try {
    size_t used = 0;
    const unsigned long long value = std::stoull(it->second, &used);
    if (used == it->second.size() && value <= max && it->second.front() != '-') return value;
  } catch (const std::exception&) {
  }
  throw HttpError(
      400, "query parameter " + name + "=" + it->second + ": must be an integer from 0 to " + std::to_string(max));
}

ApiResponse json_answer(int status, const json& body) { return {status, body.dump(), {}}; }

}  // namespace

ApiResponse fault_endpoint(FaultControl& faults, uint64_t default_seed, const ApiRequest& request) {
  const std::string source = request.method + " " + origin_form_path(request.path);
  if (request.method == "GET" || request.method == "HEAD") {
    const uint64_t since = query_number(request, "since", 0, UINT64_MAX);
    const uint64_t limit = query_number(request, "limit", 1000, FaultControl::kMaxEvents);
    return json_answer(200, faults.status(since, static_cast<size_t>(limit)));
  }
  if (request.method == "PUT" || request.method == "POST") {
    const json document = json::parse(request.body, nullptr, false);
    if (document.is_discarded()) throw InputError(source + ": the body is not JSON (expected a fault plan object)");
    faults.set(fault_plan_from_json(document, source, default_seed));  // throws before anything changes
    return json_answer(200, faults.status(UINT64_MAX, 0));
  }
  if (request.method == "DELETE") {
    faults.set(FaultPlan{});
    return json_answer(200, faults.status(UINT64_MAX, 0));
  }
  return {405,
          json{{"error", "method " + request.method + " is not allowed on " + origin_form_path(request.path) +
                             "; allowed: GET, PUT, POST, DELETE"}}
              .dump(),
          {{"Allow", "GET, PUT, POST, DELETE"}}};
}

}  // namespace lidartwin
