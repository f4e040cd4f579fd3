// JSON responses, body and query parsing for the endpoints.
#include "http_api/api_util.h"

#include <algorithm>
#include <cctype>

namespace lidartwin {

ApiResponse json_response(const nlohmann::json& body, int status) {
  ApiResponse response;
  response.status = status;
  // Replace invalid UTF-8 (from user data or unknown keys) rather than throw while answering.
  response.body = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return response;
}

ApiResponse error_response(int status, const std::string& message) {
  return json_response({{"error", message}}, status);
}

nlohmann::json parse_json(const std::string& text, const std::string& what) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    // e.what() carries the position: "parse error at line 1, column 7: syntax error ...".
    throw HttpError(400, what + " is not valid JSON: " + e.what());
  }
}

nlohmann::json parse_json_body(const ApiRequest& request, const nlohmann::json& when_empty) {
  const bool blank = std::all_of(request.body.begin(), request.body.end(),
                                 [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; });
  if (blank) return when_empty;
  return parse_json(request.body, "request body");
}

std::optional<std::string> query_value(const ApiRequest& request, std::string_view key) {
  const auto it = request.query.find(std::string(key));
  if (it == request.query.end()) return std::nullopt;
  return it->second;
}

bool query_flag(const ApiRequest& request, std::string_view key, bool default_value) {
  const auto value = query_value(request, key);
  if (!value) return default_value;
  std::string lower = *value;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "true") return true;
  if (lower == "false") return false;
  throw HttpError(400, "query parameter " + std::string(key) + ": must be true or false, got \"" + *value + "\"");
}

}  // namespace lidartwin
