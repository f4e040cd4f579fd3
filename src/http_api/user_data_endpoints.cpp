// User data (protocol doc 2.3): must answer 200 with a JSON string for FW 2.5 and >= 3.1, or
// init_client and open_source fail (protocol doc 1.4).
#include "http_api/api_util.h"
#include "http_api/routes.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin {
namespace {

nlohmann::json with_policy(const UserData& data) {
  return {{"policy", std::string(to_string(data.policy))}, {"value", data.value}};
}

ApiResponse get_user_data(Sensor& sensor, const ApiRequest& request) {
  const auto data = sensor.user_data();
  if (query_flag(request, "include_metadata", false)) return json_response(with_policy(data));
  return json_response(data.value);
}

// Body: a JSON string. The SDK adds ?policy=keep_on_config_delete only when asked to keep it.
ApiResponse put_user_data(Sensor& sensor, const ApiRequest& request) {
  auto policy = UserDataPolicy::kClearOnConfigDelete;
  if (const auto text = query_value(request, "policy")) {
    const auto parsed = user_data_policy_from_string(*text);
    if (!parsed) {
      throw HttpError(400,
                      "query parameter policy: must be \"keep_on_config_delete\" or "
                      "\"clear_on_config_delete\", got \"" +
                          *text + "\"");
    }
    policy = *parsed;
  }
  const auto body = parse_json_body(request, nlohmann::json());
  const json_reader::Location at{"PUT user/data", ""};
  if (!body.is_string()) at.fail_expected("a JSON string", body);
  sensor.set_user_data(body.get<std::string>(), policy);
  return json_response(with_policy(sensor.user_data()));
}

ApiResponse delete_user_data(Sensor& sensor, const ApiRequest&) {
  sensor.delete_user_data();
  return json_response(nlohmann::json::object());
}

}  // namespace

std::vector<Route> user_data_routes() {
  return {
      {"GET", "user/data", false, get_user_data},
      {"PUT", "user/data", false, put_user_data},
      {"DELETE", "user/data", false, delete_user_data},
  };
}

}  // namespace lidartwin
