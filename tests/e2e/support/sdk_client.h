#pragma once
// The HTTP call sequences of the real clients, request by request, as the protocol doc lists them
// (2.4 (a)-(e)). httplib stands in for libcurl; every non-2xx answer throws, as in the SDK.
#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include <httplib.h>
#include <nlohmann/json.hpp>

namespace lidartwin::e2e {

using nlohmann::json;

class SensorHttp {
 public:
  SensorHttp(const std::string& address, int port) : client_(address, port) {
    client_.set_connection_timeout(4);
    client_.set_read_timeout(4);
    client_.set_keep_alive(true);  // curl reuses one handle (2.1)
  }

  std::string get(const std::string& path) { return check("GET", path, client_.Get("/api/v1/" + path)); }
  std::string post(const std::string& path, const json& body) {
    return check("POST", path, client_.Post("/api/v1/" + path, body.dump(), "application/json"));
  }
  json get_json(const std::string& path) { return json::parse(get(path)); }
  // Raw access for the bad-request tests: no status check.
  httplib::Result raw_get(const std::string& path) { return client_.Get(path); }
  httplib::Result raw_post(const std::string& path, const std::string& body) {
    return client_.Post(path, body, "application/json");
  }

 private:
  static std::string check(const char* method, const std::string& path, const httplib::Result& result) {
    if (!result) {
      throw std::runtime_error(std::string(method) + " " + path + ": transport error (" +
                               httplib::to_string(result.error()) + ")");
    }
    if (result->status < 200 || result->status > 299) {
      throw std::runtime_error(std::string(method) + " " + path + ": [" + std::to_string(result->status) + "] " +
                               result->body);
    }
    return result->body;
  }

  httplib::Client client_;
};

// What a client asks for beyond the destination and ports.
struct ConfigRequest {
  std::optional<std::string> lidar_mode;
  std::optional<std::string> udp_profile_lidar;
  std::optional<std::string> timestamp_mode;
  uint16_t lidar_port = 0;  // 0: keep the sensor's
  uint16_t imu_port = 0;
  bool udp_dest_auto = true;
  bool force_reinit = false;
  json extra = json::object();  // more keys, e.g. ouster-ros's azimuth_window (2.4 (e) step 1)
};

// 2.4 (a) set_config for FW >= 3.1 (REST config API).
inline void set_config(SensorHttp& http, const ConfigRequest& request) {
  json config = http.get_json("sensor/config");
  const json original = config;
  if (request.lidar_mode) config["lidar_mode"] = *request.lidar_mode;
  if (request.udp_profile_lidar) config["udp_profile_lidar"] = *request.udp_profile_lidar;
  if (request.timestamp_mode) config["timestamp_mode"] = *request.timestamp_mode;
  if (request.lidar_port) config["udp_port_lidar"] = request.lidar_port;
  if (request.imu_port) config["udp_port_imu"] = request.imu_port;
  for (const auto& [key, value] : request.extra.items()) config[key] = value;
  config["operating_mode"] = "NORMAL";
  if (request.udp_dest_auto) {
    http.post("sensor/config?staging=true&reinit=false&persist=false", {{"udp_dest", "@auto"}});
    const json staged = http.get_json("sensor/config?staging=true");
    config["udp_dest"] = staged.contains("udp_ip") ? staged["udp_ip"] : staged["udp_dest"];
  }
  if (request.force_reinit || config != original) {
    http.post("sensor/config?staging=true&reinit=false&persist=false", config);
    http.post("sensor/config?staging=true&reinit=true&persist=false", json::object());
  }
}

// 2.4 (b) collect_metadata.
inline json collect_metadata(SensorHttp& http, std::chrono::seconds timeout = std::chrono::seconds(40)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (http.get_json("sensor/metadata/sensor_info").at("status") == "INITIALIZING") {
    if (std::chrono::steady_clock::now() > deadline) {
      throw std::runtime_error("A timeout occurred while waiting for the sensor to initialize.");
    }
    std::this_thread::sleep_for(std::chrono::seconds(1));
  }
  const json user_data = http.get_json("user/data");
  if (!user_data.is_string()) throw std::runtime_error("user/data is not a JSON string");
  return http.get_json("sensor/metadata");
}

// 2.4 (c) SDK-0.16 init_client(hostname, "", mode, ts_mode, lidar_port, imu_port): the caller has
// bound the sockets; their ports are requested. Returns the metadata; status must not be ERROR.
inline json sdk016_init_client(SensorHttp& http, ConfigRequest request) {
  http.get_json("sensor/metadata/sensor_info");  // SensorHttp::create
  set_config(http, request);
  json metadata = collect_metadata(http);
  const std::string status = metadata.at("sensor_info").at("status");
  if (status == "ERROR" || status == "UNCONFIGURED") throw std::runtime_error("init_client: status " + status);
  return metadata;
}

// 2.4 (d) SDK-1.0 SensorPacketSource(hostname, options): udp_dest probe, then set_config with
// flags 0, then fetch_metadata. The ports of `request`, if any, come from the options.
inline json sdk10_sensor_packet_source(SensorHttp& http, ConfigRequest request) {
  http.get_json("sensor/metadata/sensor_info");
  const json active = http.get_json("sensor/config?staging=false");
  const json original_dest = active.at("udp_dest");
  http.post("sensor/config?reinit=False&persist=False", {{"udp_dest", "@auto"}});
  const json detected = http.get_json("sensor/config?staging=true").at("udp_dest");
  http.post("sensor/config?reinit=False&persist=False", {{"udp_dest", original_dest}});
  request.udp_dest_auto = false;
  request.extra["udp_dest"] = detected;
  http.get_json("sensor/metadata/sensor_info");  // the fresh SensorHttp::create of step 4
  set_config(http, request);
  return collect_metadata(http, std::chrono::seconds(45));
}

// 2.4 (e) ouster-ros start-up with default parameters: set_config from the node parameters
// (always azimuth_window and signal_multiplier), then init_client with ephemeral ports (a second
// staged write and reinit), then get_metadata twice.
inline json ros_driver_start(SensorHttp& http, const std::string& lidar_mode, uint16_t lidar_port, uint16_t imu_port) {
  ConfigRequest parameters;
  parameters.lidar_mode = lidar_mode;
  parameters.extra = {{"azimuth_window", {0, 360000}}, {"signal_multiplier", 1}};
  set_config(http, parameters);
  ConfigRequest client = parameters;
  client.lidar_port = lidar_port;
  client.imu_port = imu_port;
  sdk016_init_client(http, client);
  http.get_json("sensor/metadata/sensor_info");
  return collect_metadata(http, std::chrono::seconds(60));
}

}  // namespace lidartwin::e2e
