#pragma once
// Helpers shared by the endpoint files: JSON responses, body and query parsing. Errors are thrown
// as HttpError / InputError and turned into 4xx responses by RequestHandler.
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "lidartwin/http_api/request_handler.h"

namespace lidartwin {

ApiResponse json_response(const nlohmann::json& body, int status = 200);
ApiResponse error_response(int status, const std::string& message);

// The body parsed as JSON; an empty body counts as `when_empty`. Throws HttpError 400 with the
// parser's position ("line 1, column 7") when it is not JSON.
nlohmann::json parse_json_body(const ApiRequest& request, const nlohmann::json& when_empty);
// `text` parsed as JSON; throws HttpError 400 naming `what` and the parse position.
nlohmann::json parse_json(const std::string& text, const std::string& what);

std::optional<std::string> query_value(const ApiRequest& request, std::string_view key);
// "true"/"false" in any letter case (the SDK sends both "false" and "False", protocol doc 2.7);
// `default_value` when absent. Throws HttpError 400 naming the parameter otherwise.
bool query_flag(const ApiRequest& request, std::string_view key, bool default_value);

}  // namespace lidartwin
