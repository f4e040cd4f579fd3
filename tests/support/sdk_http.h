#pragma once
// The Ouster SDK's HTTP side, replayed for tests: the requests its CurlClient sends (protocol doc
// 2.1) in the order of the documented call sequences (protocol doc 2.4). Non-2xx answers throw, as
// they do in the SDK.
#include <cctype>
#include <chrono>
#include <cstdio>
#include <regex>
#include <stdexcept>
#include <string>
#include <thread>

#include <httplib.h>
#include <nlohmann/json.hpp>

namespace lidartwin::test {

using nlohmann::json;

// curl_easy_escape: everything but ALPHA / DIGIT / "-" / "." / "_" / "~" is %XX-encoded.
inline std::string curl_escape(const std::string& text) {
  std::string out;
  for (unsigned char c : text) {
    if (std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~') {
      out += static_cast<char>(c);
    } else {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", c);
      out += hex;
    }
  }
  return out;
}

class SdkHttp {
 public:
  explicit SdkHttp(int port) : http_("127.0.0.1", port) {
    http_.set_keep_alive(true);    // curl reuses one handle
    http_.set_url_encode(false);   // send the target exactly as the SDK builds it
    http_.set_read_timeout(5, 0);  // SHORT timeout class (protocol doc 1.2)
  }

  std::string get(const std::string& resource) {
    return checked(http_.Get(("/api/v1/" + resource).c_str()), "GET", resource);
  }
  std::string post(const std::string& resource, const std::string& body) {
    return checked(http_.Post(("/api/v1/" + resource).c_str(), body, "application/json"), "POST", resource);
  }
  std::string put(const std::string& resource, const std::string& body) {
    return checked(http_.Put(("/api/v1/" + resource).c_str(), body, "application/json"), "PUT", resource);
  }
  json get_json(const std::string& resource) { return json::parse(get(resource)); }

 private:
  static std::string checked(const httplib::Result& result, const std::string& method, const std::string& resource) {
    if (!result) {
      throw std::runtime_error(method + " " + resource + ": " + httplib::to_string(result.error()));
    }
    if (result->status < 200 || result->status > 299) {
      throw std::runtime_error("CurlClient::execute_request failed for url: [" + resource + "] with the code: [" +
                               std::to_string(result->status) + "] " + result->body);
    }
    return result->body;
  }

  httplib::Client http_;
};

// FW detection (protocol doc 2.2): image_rev must carry a parsable vX.Y.Z of at least 2.4.
inline std::string firmware_version(const std::string& image_rev) {
  std::smatch match;
  const std::regex version(R"(v?(\d+)\.(\d+)\.(\d+))");
  if (!std::regex_search(image_rev, match, version)) throw std::runtime_error("no version");
  return match[1].str() + "." + match[2].str() + "." + match[3].str();
}

// 2.4 (a) with the FW >= 3.1 REST calls of SDK >= 0.16.
inline void set_config(SdkHttp& http, const json& requested, bool udp_dest_auto, bool force_reinit = false,
                       bool persist = false) {
  json p = http.get_json("sensor/config");
  const json p0 = p;
  for (const auto& [key, value] : requested.items()) p[key] = value;
  if (udp_dest_auto || requested.value("udp_dest", "") == "@auto") {
    http.post("sensor/config?staging=true&reinit=false&persist=false", R"({"udp_dest":"@auto"})");
    const json staged = http.get_json("sensor/config?staging=true");
    if (staged.contains("udp_ip")) {
      p["udp_ip"] = staged["udp_ip"];
      p["udp_dest"] = staged["udp_ip"];
    } else {
      p["udp_dest"] = staged.at("udp_dest");
    }
    if (staged.contains("udp_dest_zm")) p["udp_dest_zm"] = staged["udp_dest_zm"];
  }
  if (force_reinit || p != p0) {
    http.post("sensor/config?staging=true&reinit=false&persist=false", p.dump());
    http.post("sensor/config?staging=true&reinit=true&persist=false", "{}");
  }
  if (persist) http.post("sensor/config?persist=true&reinit=false", "{}");
}

// 2.4 (b): poll while INITIALIZING (the SDK sleeps 1 s; 20 ms here), user data, metadata.
inline json collect_metadata(SdkHttp& http) {
  for (int polls = 0; http.get_json("sensor/metadata/sensor_info").at("status") == "INITIALIZING"; ++polls) {
    if (polls > 200) throw std::runtime_error("A timeout occurred while waiting for the sensor");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const json user_data = http.get_json("user/data");
  if (!user_data.is_string()) throw std::runtime_error("user/data is not a JSON string");
  return http.get_json("sensor/metadata");
}

// 2.4 (d) 2: ask the sensor what "@auto" means without changing the active config.
inline std::string auto_detected_udp_dest(SdkHttp& http) {
  const std::string original = http.get_json("sensor/config?staging=false").value("udp_dest", "");
  http.post("sensor/config?reinit=False&persist=False", R"({"udp_dest":"@auto"})");
  const std::string detected = http.get_json("sensor/config?staging=true").at("udp_dest");
  http.post("sensor/config?reinit=False&persist=False", json({{"udp_dest", original}}).dump());
  return detected;
}

// 2.4 (a) as SDK <= 0.15 does it for every FW >= 2.4: the cmd API only (protocol doc 2.2).
inline void set_config_cmd(SdkHttp& http, const json& requested, bool udp_dest_auto, bool persist) {
  json p = json::parse(http.get("sensor/cmd/get_config_param?args=active"));
  const json p0 = p;
  for (const auto& [key, value] : requested.items()) p[key] = value;
  if (udp_dest_auto) {
    if (http.get("sensor/cmd/set_udp_dest_auto") != "{}") throw std::runtime_error("body != {}");
    p["udp_dest"] = json::parse(http.get("sensor/cmd/get_config_param?args=staged")).at("udp_dest");
  }
  if (p != p0) {
    // SensorHttpImp::execute compares these bodies byte for byte.
    if (http.get("sensor/cmd/set_config_param?args=.+" + curl_escape(p.dump())) != "\"set_config_param\"") {
      throw std::runtime_error("set_config_param body");
    }
    if (http.get("sensor/cmd/reinitialize") != "{}") throw std::runtime_error("reinitialize body");
  }
  if (persist && http.get("sensor/cmd/save_config_params") != "{}") {
    throw std::runtime_error("save_config_params body");
  }
}

}  // namespace lidartwin::test
