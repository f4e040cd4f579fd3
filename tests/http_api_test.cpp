// The HTTP API over loopback: the SDK's and ouster-ros's exact call sequences (protocol doc 2.4),
// the cmd API of SDK <= 0.15, proxy-form request lines, and bad requests (4xx, config unchanged).
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <ostream>
#include <sstream>
#include <thread>
#include <vector>

#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "lidartwin/http_api/http_server.h"
#include "lidartwin/sensor/sensor.h"
#include "support/raw_http.h"
#include "support/sdk_http.h"

namespace {

using lidartwin::HttpServer;
using lidartwin::Sensor;
using lidartwin::test::SdkHttp;
using nlohmann::json;
using testing::HasSubstr;

lidartwin::SensorIdentity test_identity() {
  lidartwin::SensorIdentity identity;
  for (int row = 0; row < 64; ++row) {
    identity.beams.altitude_deg.push_back(16.6 - 0.52 * row);
    identity.beams.azimuth_deg.push_back(std::array{3.1, 0.9, -1.2, -3.3}[row % 4]);
  }
  identity.beams.lidar_origin_to_beam_origin_mm = 12.163;
  identity.limits.lidar_modes = {"512x10", "512x20", "1024x10", "1024x20", "2048x10"};
  return identity;
}

lidartwin::SensorOptions test_options() {
  lidartwin::SensorOptions options;
  // Not the loopback address, so that resolving "@auto" to 127.0.0.1 is visible.
  options.config_overrides = {{"udp_dest", "192.0.2.1"}};
  options.initializing_time = std::chrono::milliseconds(100);  // clients must poll through it
  return options;
}

// What the SDK's parse_and_validate_metadata needs (protocol doc 1.7, 3.1 "crit" keys).
void expect_sdk_parsable(const json& metadata) {
  for (const char* section : {"sensor_info", "beam_intrinsics", "imu_intrinsics", "lidar_intrinsics", "config_params",
                              "lidar_data_format", "calibration_status"}) {
    ASSERT_TRUE(metadata.contains(section)) << section;
  }
  const auto& info = metadata["sensor_info"];
  for (const char* key : {"build_date", "build_rev", "image_rev", "prod_line", "prod_pn", "status"}) {
    EXPECT_TRUE(info.at(key).is_string()) << key;
  }
  EXPECT_TRUE(info.at("prod_sn").is_string());
  EXPECT_TRUE(info.at("initialization_id").is_number_integer());
  const auto& config = metadata["config_params"];
  EXPECT_FALSE(config.at("udp_dest").get<std::string>().empty());
  EXPECT_NE(config.at("udp_port_lidar"), 0);
  EXPECT_NE(config.at("udp_port_imu"), 0);
  EXPECT_TRUE(config.at("lidar_mode").is_string());
  const auto& format = metadata["lidar_data_format"];
  const int rows = format.at("pixels_per_column");
  EXPECT_EQ(metadata["beam_intrinsics"].at("beam_altitude_angles").size(), size_t(rows));
  EXPECT_EQ(metadata["beam_intrinsics"].at("beam_azimuth_angles").size(), size_t(rows));
  EXPECT_EQ(format.at("pixel_shift_by_row").size(), size_t(rows));
  EXPECT_EQ(format.at("udp_profile_lidar"), config.at("udp_profile_lidar"));
  for (const char* key : {"columns_per_frame", "columns_per_packet", "column_window", "fps"}) {
    EXPECT_TRUE(format.contains(key)) << key;
  }
}

class HttpApi : public testing::Test {
 protected:
  explicit HttpApi(lidartwin::SensorOptions options = test_options())
      : sensor_(test_identity(), std::move(options)), server_(sensor_, {.address = "127.0.0.1", .port = 0}) {
    server_.start();
    sensor_.subscribe([this](const Sensor::StreamConfigPtr& config) {
      std::lock_guard lock(notified_mutex_);
      notified_ = config;
    });
  }

  // What the sensor last told its subscribers (the streamer), from an HTTP worker thread.
  Sensor::StreamConfigPtr notified() {
    std::lock_guard lock(notified_mutex_);
    return notified_;
  }

  int port() const { return server_.port(); }
  httplib::Client client() const {
    httplib::Client http("127.0.0.1", port());
    http.set_url_encode(false);
    return http;
  }

  Sensor sensor_;
  HttpServer server_;
  std::mutex notified_mutex_;
  Sensor::StreamConfigPtr notified_;
};

// 2.4 (c): init_client(hostname, "", mode, ts_mode, lidar_port=0, imu_port=0) binds ephemeral
// ports, then set_config (a) with CONFIG_UDP_DEST_AUTO, then collect_metadata (b).
TEST_F(HttpApi, Sdk016InitClientWithAutoDestAndEphemeralPorts) {
  SdkHttp http(port());
  const auto info = http.get_json("sensor/metadata/sensor_info");
  EXPECT_EQ(info.at("prod_line"), "OS-1-64");
  EXPECT_EQ(lidartwin::test::firmware_version(info.at("image_rev")), "3.1.0");
  const uint32_t init_id_before = info.at("initialization_id");

  lidartwin::test::set_config(http,
                              {{"lidar_mode", "1024x10"},
                               {"timestamp_mode", "TIME_FROM_INTERNAL_OSC"},
                               {"udp_port_lidar", 41234},
                               {"udp_port_imu", 41235},
                               {"operating_mode", "NORMAL"}},
                              /*udp_dest_auto=*/true);
  const json metadata = lidartwin::test::collect_metadata(http);
  expect_sdk_parsable(metadata);
  const auto& status = metadata["sensor_info"]["status"];
  EXPECT_TRUE(status != "ERROR" && status != "UNCONFIGURED");
  EXPECT_EQ(metadata["config_params"]["udp_dest"], "127.0.0.1");
  EXPECT_EQ(metadata["config_params"]["udp_port_lidar"], 41234);
  EXPECT_NE(metadata["sensor_info"]["initialization_id"], init_id_before);

  const auto stream = notified();  // what the streamer was told
  EXPECT_EQ(stream->udp_dest, (std::array<uint8_t, 4>{127, 0, 0, 1}));
  EXPECT_EQ(stream->udp_port_lidar, 41234);
  EXPECT_EQ(stream->udp_port_imu, 41235);
  EXPECT_EQ(stream->init_id, metadata["sensor_info"]["initialization_id"]);
}

// 2.4 (a) step 3: the staged GET right after the "@auto" write shows the resolved address.
TEST_F(HttpApi, AutoIsResolvedInTheNextStagedGet) {
  SdkHttp http(port());
  http.post("sensor/config?staging=true&reinit=false&persist=false", R"({"udp_dest":"@auto"})");
  EXPECT_EQ(http.get_json("sensor/config?staging=true").at("udp_dest"), "127.0.0.1");
  EXPECT_EQ(http.get_json("sensor/config").at("udp_dest"), "192.0.2.1");  // active unchanged
}

// 2.4 (d): SensorPacketSource (open_source, ouster-cli): probe "@auto" with reinit=False (no
// staging parameter), restore, then set_config and fetch_metadata.
TEST_F(HttpApi, SensorPacketSourceSequence) {
  SdkHttp http(port());
  http.get_json("sensor/metadata/sensor_info");
  const auto active = http.get_json("sensor/config?staging=false");
  const uint32_t init_id = sensor_.stream_config()->init_id;

  EXPECT_EQ(lidartwin::test::auto_detected_udp_dest(http), "127.0.0.1");
  EXPECT_EQ(http.get_json("sensor/config?staging=true").at("udp_dest"), "192.0.2.1");  // restored
  EXPECT_EQ(sensor_.stream_config()->init_id, init_id);                                // the probe did not reinitialize
  EXPECT_EQ(http.get_json("sensor/config"), active);

  lidartwin::test::set_config(http, {{"udp_dest", "127.0.0.1"}, {"operating_mode", "NORMAL"}}, false);
  const json metadata = lidartwin::test::collect_metadata(http);
  expect_sdk_parsable(metadata);
  EXPECT_EQ(metadata["config_params"]["udp_dest"], "127.0.0.1");
  EXPECT_EQ(metadata["config_params"]["udp_port_lidar"], 7502);  // ports kept (options unset)
}

// 2.4 (e): ouster-ros with default parameters: set_config with the ROS config and auto dest,
// then init_client with ephemeral ports (set_config again), then get_metadata.
TEST_F(HttpApi, OusterRosTrace) {
  SdkHttp http(port());
  const json ros_config = {{"azimuth_window", {0, 360000}},
                           {"signal_multiplier", 1},
                           {"lidar_mode", "1024x10"},
                           {"timestamp_mode", "TIME_FROM_INTERNAL_OSC"}};
  http.get_json("sensor/metadata/sensor_info");                 // SensorHttp::create
  lidartwin::test::set_config(http, ros_config, true);          // configure_sensor
  const auto generation = sensor_.stream_config()->generation;  // first reinit done
  http.get_json("sensor/metadata/sensor_info");                 // init_client: create
  json with_ports = ros_config;
  with_ports.update({{"udp_port_lidar", 50001}, {"udp_port_imu", 50002}, {"operating_mode", "NORMAL"}});
  lidartwin::test::set_config(http, with_ports, true);
  EXPECT_EQ(sensor_.stream_config()->generation, generation + 1);
  const json first = lidartwin::test::collect_metadata(http);
  http.get_json("sensor/metadata/sensor_info");  // get_metadata: create
  const json second = lidartwin::test::collect_metadata(http);
  expect_sdk_parsable(second);
  EXPECT_EQ(first, second);
  EXPECT_EQ(second["config_params"]["udp_port_lidar"], 50001);
  EXPECT_EQ(second["config_params"]["udp_port_imu"], 50002);
  EXPECT_EQ(second["config_params"]["udp_dest"], "127.0.0.1");
  EXPECT_EQ(second["sensor_info"]["initialization_id"], sensor_.stream_config()->init_id);
}

// SDK <= 0.15 (protocol doc 2.2): FW from system/firmware, config through the cmd API only.
TEST_F(HttpApi, Sdk015CmdApiSequence) {
  SdkHttp http(port());
  EXPECT_EQ(http.get("system/firmware"), R"({"fw":"ousteros-image-prod-bootes-v3.1.0+20240426041747"})");
  lidartwin::test::set_config_cmd(http,
                                  {{"udp_port_lidar", 45000},
                                   {"udp_port_imu", 45001},
                                   {"lidar_mode", "2048x10"},
                                   {"unknown_to_fw", {{"kept", true}}}},
                                  /*udp_dest_auto=*/true, /*persist=*/true);
  const auto active = json::parse(http.get("sensor/cmd/get_config_param?args=active"));
  EXPECT_EQ(active.at("udp_dest"), "127.0.0.1");
  EXPECT_EQ(active.at("lidar_mode"), "2048x10");
  EXPECT_EQ(active.at("unknown_to_fw"), json({{"kept", true}}));
  EXPECT_EQ(http.get("sensor/cmd/get_config_param?args=active+udp_port_lidar"), "45000");
  // One key at a time, as set_config_param(key, value) sends it.
  EXPECT_EQ(http.get("sensor/cmd/set_config_param?args=udp_port_imu+" + lidartwin::test::curl_escape("46000")),
            "\"set_config_param\"");
  EXPECT_EQ(json::parse(http.get("sensor/cmd/get_config_param?args=staged")).at("udp_port_imu"), 46000);
  const json metadata = lidartwin::test::collect_metadata(http);
  expect_sdk_parsable(metadata);
  EXPECT_EQ(metadata["lidar_data_format"]["columns_per_frame"], 2048);
}

TEST_F(HttpApi, ProxyFormRequestLinesWork) {
  const auto received =
      lidartwin::test::raw_exchange(port(),
                                    "GET http://127.0.0.1/api/v1/sensor/metadata/sensor_info HTTP/1.1\r\n"
                                    "Host: 127.0.0.1\r\nConnection: close\r\n\r\n");
  EXPECT_THAT(received, testing::StartsWith("HTTP/1.1 200"));
  EXPECT_EQ(json::parse(lidartwin::test::last_body(received)).at("prod_line"), "OS-1-64");

  const std::string body = R"({"udp_dest":"@auto"})";
  const auto posted = lidartwin::test::raw_exchange(
      port(),
      "POST http://127.0.0.1:80/api/v1/sensor/config?staging=true&reinit=false&persist=false "
      "HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: " +
          std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body);
  EXPECT_THAT(posted, testing::StartsWith("HTTP/1.1 200"));
  EXPECT_EQ(sensor_.staged_config().at("udp_dest"), "127.0.0.1");
}

// curl keeps one connection (protocol doc 2.1): requests one after the other on one socket.
// (cpp-httplib does not support pipelining, and curl no longer pipelines.)
TEST_F(HttpApi, KeepAliveServesSeveralRequestsOnOneConnection) {
  lidartwin::test::RawConnection connection(port());
  for (int i = 0; i < 3; ++i) {
    connection.send("GET /api/v1/sensor/metadata/sensor_info HTTP/1.1\r\nHost: x\r\n\r\n");
    const auto response = connection.read_response();
    EXPECT_THAT(response, testing::StartsWith("HTTP/1.1 200")) << i;
    EXPECT_THAT(response, HasSubstr("Keep-Alive"));
  }
  connection.send(
      "POST /api/v1/sensor/config?staging=true&reinit=false&persist=false HTTP/1.1\r\n"
      "Host: x\r\nContent-Length: 2\r\n\r\n{}");
  EXPECT_THAT(connection.read_response(), testing::StartsWith("HTTP/1.1 200"));
}

// Old curl sends "Expect: 100-continue" for bodies over 1 KB (protocol doc 2.1).
TEST_F(HttpApi, ExpectContinueIsAnswered) {
  json full = sensor_.active_config();
  full["padding"] = std::string(1500, 'x');
  const std::string body = full.dump();
  const auto received =
      lidartwin::test::raw_exchange(port(),
                                    "POST /api/v1/sensor/config?staging=true&reinit=false&persist=false HTTP/1.1\r\n"
                                    "Host: x\r\nExpect: 100-continue\r\nContent-Type: application/json\r\n"
                                    "Content-Length: " +
                                        std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body);
  EXPECT_THAT(received, testing::StartsWith("HTTP/1.1 100 Continue"));
  EXPECT_THAT(received, HasSubstr("HTTP/1.1 200"));
  EXPECT_EQ(sensor_.staged_config().at("padding").get<std::string>().size(), 1500u);
}

struct BadRequest {
  std::string method;
  std::string target;  // below /api/v1/ unless it starts with "/"
  std::string body;
  int status;
  std::string message_part;
};

void PrintTo(const BadRequest& r, std::ostream* os) { *os << r.method << " " << r.target; }

class HttpApiRejects : public HttpApi, public testing::WithParamInterface<BadRequest> {};

TEST_P(HttpApiRejects, WithAnExplanationAndNoChange) {
  const auto& bad = GetParam();
  const auto active = sensor_.active_config();
  const auto staged = sensor_.staged_config();
  const auto init_id = sensor_.stream_config()->init_id;
  auto http = client();
  const std::string target = bad.target.starts_with("/") ? bad.target : "/api/v1/" + bad.target;
  httplib::Request request;
  request.method = bad.method;
  request.path = target;
  request.body = bad.body;
  if (!bad.body.empty()) request.set_header("Content-Type", "application/json");
  const auto result = http.send(request);
  ASSERT_TRUE(result) << httplib::to_string(result.error());
  EXPECT_EQ(result->status, bad.status) << result->body;
  EXPECT_EQ(result->get_header_value("Content-Type"), "application/json");
  const auto body = json::parse(result->body);
  EXPECT_THAT(body.at("error").get<std::string>(), HasSubstr(bad.message_part));
  EXPECT_EQ(sensor_.active_config(), active);
  EXPECT_EQ(sensor_.staged_config(), staged);
  EXPECT_EQ(sensor_.stream_config()->init_id, init_id);
}

const std::string kStaged = "sensor/config?staging=true&reinit=false&persist=false";
const std::string kApply = "sensor/config?staging=true&reinit=true&persist=false";

INSTANTIATE_TEST_SUITE_P(
    BadInput, HttpApiRejects,
    testing::Values(
        BadRequest{"POST", kStaged, R"({"udp_dest": })", 400, "line 1, column 14"},
        BadRequest{"POST", kApply, R"({"lidar_mode": "2048x10",)", 400, "not valid JSON"},
        BadRequest{"POST", kStaged, R"({"udp_port_lidar": "7502"})", 400,
                   R"(POST sensor/config: /udp_port_lidar: must be an integer in [0, 65535], got a string "7502")"},
        BadRequest{"POST", kStaged, R"({"azimuth_window": [0, 400000]})", 400, "azimuth_window"},
        BadRequest{"POST", kStaged, R"({"lidar_mode": "1024x15"})", 400, "lidar_mode"},
        BadRequest{"POST", kStaged, R"({"signal_multiplier": 4})", 400, "signal_multiplier"},
        BadRequest{"POST", kStaged, R"([1, 2])", 400, "JSON object"},
        // Valid key plus invalid key with reinit: nothing applied, no reinit.
        BadRequest{"POST", kApply, R"({"lidar_mode": "2048x10", "udp_port_imu": 1e9})", 400, "udp_port_imu"},
        BadRequest{"POST", "sensor/config?reinit=maybe", "{}", 400, "reinit"},
        BadRequest{"GET", "sensor/config?staging=yes", "", 400, "staging"},
        BadRequest{"GET", "sensor/cmd/set_config_param?args=.+%7Bnope", "", 400, "not valid JSON"},
        BadRequest{"GET", "sensor/cmd/set_config_param?args=udp_port_lidar+x", "", 400,
                   R"(set_config_param args: /udp_port_lidar: must be an integer in [0, 65535], got a string "x")"},
        BadRequest{"GET", "sensor/cmd/get_config_param?args=future", "", 400, "active"},
        BadRequest{"GET", "sensor/cmd/get_config_param", "", 400, "args"},
        BadRequest{"PUT", "user/data", "42", 400, "PUT user/data: /: must be a JSON string, got a number 42"},
        BadRequest{"PUT", "user/data?policy=forever", "\"x\"", 400, "policy"},
        BadRequest{"GET", "sensor/nope", "", 404, "unknown endpoint"},
        BadRequest{"GET", "/index.html", "", 404, "/api/v1/"},
        BadRequest{"GET", "sensor/metadata/nope", "", 404, "lidar_data_format"},
        BadRequest{"GET", "zone_monitor/active/zip", "", 404, "zone"},
        BadRequest{"DELETE", "sensor/config", "", 405, "GET, POST"},
        BadRequest{"POST", "sensor/metadata", "{}", 405, "GET"}));

TEST_F(HttpApi, WrongMethodListsTheAllowedOnes) {
  const auto result = client().Delete("/api/v1/sensor/config");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 405);
  EXPECT_EQ(result->get_header_value("Allow"), "GET, POST");
}

TEST_F(HttpApi, HugeBodiesAre413AndTheServerStaysUp) {
  const auto staged = sensor_.staged_config();
  const std::string huge = "{\"x\":\"" + std::string(3 << 20, 'a') + "\"}";
  auto http = client();
  const auto result = http.Post(("/api/v1/" + kStaged).c_str(), huge, "application/json");
  ASSERT_TRUE(result) << httplib::to_string(result.error());
  EXPECT_EQ(result->status, 413);
  EXPECT_THAT(json::parse(result->body).at("error").get<std::string>(), HasSubstr("too large"));

  // Chunked bodies have no Content-Length for httplib to check: our own limit applies.
  std::string chunked = "POST /api/v1/" + kStaged +
                        " HTTP/1.1\r\nHost: x\r\n"
                        "Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n";
  const std::string chunk(64 * 1024, 'a');
  for (int i = 0; i < 40; ++i) chunked += "10000\r\n" + chunk + "\r\n";
  chunked += "0\r\n\r\n";
  const auto received = lidartwin::test::raw_exchange(port(), chunked);
  EXPECT_THAT(received, testing::StartsWith("HTTP/1.1 413"));
  EXPECT_EQ(sensor_.staged_config(), staged);
  EXPECT_EQ(client().Get("/api/v1/sensor/config")->status, 200);
}

TEST_F(HttpApi, MalformedRequestLineGetsAJson400) {
  lidartwin::test::RawConnection connection(port());
  connection.send("HELLO\r\n\r\n");
  const auto received = connection.read_response();
  EXPECT_THAT(received, testing::StartsWith("HTTP/1.1 400"));
  EXPECT_THAT(received, HasSubstr("application/json"));
  EXPECT_THAT(lidartwin::test::last_body(received), HasSubstr("malformed"));
}

TEST_F(HttpApi, PlainPostAppliesAndReinitializes) {
  const auto init_id = sensor_.stream_config()->init_id;
  const auto result = client().Post("/api/v1/sensor/config", R"({"lidar_mode":"512x20"})", "application/json");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 200);
  EXPECT_EQ(sensor_.active_config().at("lidar_mode"), "512x20");
  EXPECT_NE(sensor_.stream_config()->init_id, init_id);
  EXPECT_EQ(notified()->metadata.format.columns_per_frame, 512);
}

TEST_F(HttpApi, EveryMetadataSectionIsServedByName) {
  SdkHttp http(port());
  const auto metadata = http.get_json("sensor/metadata");
  for (const auto& [name, section] : metadata.items()) {
    if (name == "sensor_info") continue;  // its status may change between the two GETs
    EXPECT_EQ(http.get_json("sensor/metadata/" + name), section) << name;
  }
  EXPECT_TRUE(metadata.contains("imu_data_format"));
  EXPECT_EQ(http.get_json("sensor/metadata/sensor_info").at("prod_sn"), "122201000123");
}

TEST_F(HttpApi, UserDataRoundTrip) {
  SdkHttp http(port());
  EXPECT_EQ(http.get("user/data"), "\"\"");
  http.put("user/data?policy=keep_on_config_delete", R"("hello \"world\"")");
  EXPECT_EQ(http.get_json("user/data"), "hello \"world\"");
  EXPECT_EQ(http.get_json("user/data?include_metadata=true"),
            json({{"policy", "keep_on_config_delete"}, {"value", "hello \"world\""}}));
  http.put("user/data", "\"plain\"");
  EXPECT_EQ(http.get_json("user/data?include_metadata=True").at("policy"), "clear_on_config_delete");
  ASSERT_EQ(client().Delete("/api/v1/user/data")->status, 200);
  EXPECT_EQ(http.get("user/data"), "\"\"");
}

TEST_F(HttpApi, ReadOnlyStatusEndpoints) {
  SdkHttp http(port());
  lidartwin::StreamStats stats;
  stats.lidar_packets_sent = 1234;
  sensor_.set_stream_stats(stats);
  const auto telemetry = http.get_json("sensor/telemetry");
  EXPECT_EQ(telemetry.at("phase_lock_status"), "DISABLED");
  EXPECT_EQ(telemetry.at("lidartwin").at("lidar_packets_sent"), 1234);
  EXPECT_GT(http.get_json("time/system").at("realtime").get<double>(), 1.6e9);
  EXPECT_EQ(http.get_json("time/sensor").at("timestamp").at("mode"), "TIME_FROM_INTERNAL_OSC");
  EXPECT_TRUE(http.get_json("time/ptp").contains("profile"));
  const auto alerts = http.get_json("sensor/alerts");
  EXPECT_TRUE(alerts.at("active").is_array() && alerts.at("log").is_array());
  EXPECT_EQ(http.get_json("system/network").at("hostname"), "os-122201000123");
}

TEST_F(HttpApi, ConcurrentClientsAreServed) {
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      try {
        SdkHttp http(port());
        for (int i = 0; i < 20; ++i) {
          http.get_json("sensor/metadata/sensor_info");
          http.post(kStaged, json({{"udp_port_lidar", 30000 + t * 100 + i}}).dump());
          if (i % 5 == 0) http.post(kApply, "{}");
        }
      } catch (const std::exception&) {
        ++failures;
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(failures.load(), 0);
}

// A keep-alive client holds its connection, and httplib the thread serving it, until it goes
// quiet for the keep-alive time-out (5 s). Fifty such clients, each served once and then idle, do
// not hold up the next ones: each is answered at once (with a fixed pool of 8 threads, the 9th
// waited 5 s for the first to time out).
TEST_F(HttpApi, IdleKeepAliveClientsDoNotHoldUpTheNextOnes) {
  std::vector<std::unique_ptr<httplib::Client>> clients;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 51; ++i) {
    auto http = std::make_unique<httplib::Client>("127.0.0.1", port());
    http->set_keep_alive(true);
    http->set_read_timeout(10, 0);
    const auto response = http->Get("/api/v1/sensor/metadata/sensor_info");
    ASSERT_TRUE(response) << "client " << i << ": " << httplib::to_string(response.error());
    EXPECT_EQ(response->status, 200) << "client " << i;
    clients.push_back(std::move(http));  // stays connected, idle
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 2.0) << "51 keep-alive clients, one request each";
  // Every one of them is still served on its own connection.
  for (size_t i = 0; i < clients.size(); ++i) {
    const auto again = clients[i]->Get("/api/v1/sensor/metadata/sensor_info");
    ASSERT_TRUE(again) << "client " << i << " again";
    EXPECT_EQ(again->status, 200);
  }
}

// The nice value of each of this process's threads (/proc/self/task/*/stat, field 19).
std::vector<int> thread_nice_values() {
  std::vector<int> out;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream in(task.path() / "stat");
    std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::istringstream fields(stat.substr(stat.rfind(')') + 2));  // after "pid (comm) "
    std::string field;
    for (int k = 3; k <= 19 && fields >> field; ++k) {
      if (k == 19) out.push_back(std::stoi(field));
    }
  }
  return out;
}

// A sensor's lidar data comes before its web server: the threads that serve connections run at
// nice 10 (stream_bench --http-load 50 on two cores: 85 % of an OS1-128 2048x10 stream's packets
// went out un-rendered at equal priority, none at nice 10); the rest of the process is unchanged.
TEST_F(HttpApi, ConnectionsAreServedBelowThePriorityOfTheStream) {
  httplib::Client http("127.0.0.1", port());
  http.set_keep_alive(true);  // its thread stays with the connection
  ASSERT_TRUE(http.Get("/api/v1/sensor/metadata/sensor_info"));
  const std::vector<int> nice = thread_nice_values();
  EXPECT_EQ(std::count(nice.begin(), nice.end(), 10), 1) << "the connection's thread";
  EXPECT_GE(std::count(nice.begin(), nice.end(), 0), 2) << "the test's and the accept loop's threads";
}

std::filesystem::path state_file_path() {
  return std::filesystem::temp_directory_path() / ("lidartwin_http_state_" + std::to_string(::getpid()) + ".json");
}

lidartwin::SensorOptions with_state_file() {
  auto options = test_options();
  std::filesystem::remove(state_file_path());
  options.state_file = state_file_path();
  return options;
}

class HttpApiPersist : public HttpApi {
 protected:
  HttpApiPersist() : HttpApi(with_state_file()) {}
  ~HttpApiPersist() override { std::filesystem::remove(state_file_path()); }
};

TEST_F(HttpApiPersist, PersistSavesForTheNextStart) {
  SdkHttp http(port());
  lidartwin::test::set_config(http, {{"lidar_mode", "2048x10"}}, false, false, /*persist=*/true);
  Sensor restarted(test_identity(), {.state_file = state_file_path()});
  EXPECT_EQ(restarted.active_config().at("lidar_mode"), "2048x10");
  EXPECT_EQ(restarted.active_config().at("udp_dest"), "192.0.2.1");
}

TEST(HttpServer, PortInUseIsExplained) {
  lidartwin::Sensor sensor(test_identity());
  HttpServer first(sensor, {.address = "127.0.0.1", .port = 0});
  first.start();
  HttpServer second(sensor, {.address = "127.0.0.1", .port = first.port()});
  try {
    second.start();
    FAIL() << "bound twice";
  } catch (const lidartwin::BindError& e) {
    EXPECT_EQ(e.error_number(), EADDRINUSE);
    EXPECT_THAT(e.what(), HasSubstr("in use"));
  }
  first.stop();
  first.stop();  // idempotent
}

TEST(HttpServer, EachSensorCanHaveItsOwnLoopbackAddress) {
  lidartwin::Sensor sensor(test_identity());
  HttpServer server(sensor, {.address = "127.0.0.2", .port = 0});
  server.start();
  httplib::Client http("127.0.0.2", server.port());
  const auto result = http.Post("/api/v1/sensor/config?staging=true&reinit=false&persist=false",
                                R"({"udp_dest":"@auto"})", "application/json");
  ASSERT_TRUE(result);
  EXPECT_EQ(result->status, 200);
  EXPECT_EQ(sensor.staged_config().at("udp_dest"), "127.0.0.1");  // the client's address
  EXPECT_EQ(json::parse(http.Get("/api/v1/system/network")->body).at("ipv4").at("addr"), "127.0.0.2/8");
}

TEST(HttpServer, AnAddressOfAnotherHostIsExplained) {
  lidartwin::Sensor sensor(test_identity());
  HttpServer server(sensor, {.address = "192.0.2.55", .port = 0});  // TEST-NET-1, not local
  EXPECT_THAT([&] { server.start(); },
              testing::ThrowsMessage<lidartwin::BindError>(HasSubstr("no such local address")));
}

// Protocol doc 2.1: the remedies for port 80 (the root-only suite binds it for real).
TEST(HttpServer, PermissionDeniedOnPort80ExplainsTheRemedies) {
  const std::string message = lidartwin::describe_bind_error("127.0.0.1", 80, EACCES);
  EXPECT_THAT(message, HasSubstr("root"));
  EXPECT_THAT(message, HasSubstr("setcap cap_net_bind_service=+ep"));
  EXPECT_THAT(message, HasSubstr("sysctl net.ipv4.ip_unprivileged_port_start=80"));
  EXPECT_THAT(message, HasSubstr("--http-port 8080"));
  EXPECT_THAT(message, HasSubstr("http_proxy=http://127.0.0.1:8080"));
  if (::geteuid() == 0) GTEST_SKIP() << "root may bind port 80; only the message is checked";
  lidartwin::Sensor sensor(test_identity());
  HttpServer server(sensor, {.address = "127.0.0.1", .port = 80});
  EXPECT_THAT([&] { server.start(); }, testing::ThrowsMessage<lidartwin::BindError>(HasSubstr("setcap")));
}

}  // namespace
