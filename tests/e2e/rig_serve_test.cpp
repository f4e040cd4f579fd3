// `lidartwin serve --rig FILE` (issue 26): one process drives a vehicle's sensors, each a sensor of
// its own to its clients (address, serial number, product, config state machine), all in one scene
// and one motion. Tested with the shipped example rig (rigs/vehicle.json) on loopback addresses,
// with ephemeral HTTP ports so that no root is needed.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e::rig_serve_test {
namespace {

namespace fs = std::filesystem;

const std::string kExampleRig = std::string(LIDARTWIN_SOURCE_DIR) + "/rigs/vehicle.json";

struct RigSensor {
  std::string address;
  std::string prod_line;
  size_t beams;
};
const std::vector<RigSensor> kSensors{
    {"127.0.0.2", "OS-1-128", 128}, {"127.0.0.3", "OS-0-32-U1", 32}, {"127.0.0.4", "OS-0-32-U1", 32}};

std::vector<std::string> rig_args(const std::string& rig_file) {
  return {"--rig", rig_file, "--http-port", "0", "--scene", room_scene().string(), "--pose", kRoomPose};
}

struct Client {
  UdpSocket lidar;
  UdpSocket imu;
  Metadata metadata;
};

void connect(const Daemon& daemon, const std::string& address, Client& client, const std::string& mode) {
  SensorHttp http(address, daemon.port_of(address));
  ConfigRequest request;
  request.lidar_port = client.lidar.port();
  request.imu_port = client.imu.port();
  request.lidar_mode = mode;
  client.metadata = parse(sdk10_sensor_packet_source(http, request));
}

TEST(RigServe, EachSensorIsItsOwnAndOnesReinitAnothersBadRequestAndStopLeaveTheThirdStreaming) {
  Daemon daemon(Daemon::Rig{}, kSensors.back().address, rig_args(kExampleRig));
  std::set<std::string> serials;
  for (const RigSensor& expected : kSensors) {
    ASSERT_GT(daemon.port_of(expected.address), 0) << daemon.log();
    SensorHttp http(expected.address, daemon.port_of(expected.address));
    const json metadata = http.get_json("sensor/metadata");
    EXPECT_EQ(metadata.at("sensor_info").at("prod_line"), expected.prod_line) << expected.address;
    EXPECT_EQ(metadata.at("beam_intrinsics").at("beam_altitude_angles").size(), expected.beams);
    serials.insert(metadata.at("sensor_info").at("prod_sn").get<std::string>());
  }
  EXPECT_EQ(serials.size(), kSensors.size()) << "each sensor has its own serial number";

  // Three clients, each with its own sensor's packets, from that sensor's address.
  Client roof, left, right;
  connect(daemon, "127.0.0.2", roof, "512x10");
  connect(daemon, "127.0.0.3", left, "512x10");
  connect(daemon, "127.0.0.4", right, "512x10");
  ScanBatcher roof_batcher(roof.metadata.format);
  expect_complete_scans(receive_scans(roof.lidar, roof_batcher, 3, std::chrono::seconds(15), "127.0.0.2"),
                        roof.metadata, 3);
  ScanBatcher left_batcher(left.metadata.format);
  expect_complete_scans(receive_scans(left.lidar, left_batcher, 3, std::chrono::seconds(15), "127.0.0.3"),
                        left.metadata, 3);
  ScanBatcher right_batcher(right.metadata.format);
  expect_complete_scans(receive_scans(right.lidar, right_batcher, 3, std::chrono::seconds(15), "127.0.0.4"),
                        right.metadata, 3);

  // While the roof's client receives 11 scans: the left sensor is reconfigured (a new mode: a reinit,
  // a new init_id); the right one gets a bad request, which it refuses, and is then stopped the way
  // a client stops a sensor (operating_mode STANDBY). The roof's scans stay complete, consecutive
  // and of one session throughout; the left streams its new mode; the right falls silent.
  std::thread others([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    Client again;
    connect(daemon, "127.0.0.3", again, "1024x10");
    EXPECT_NE(again.metadata.sensor_info.initialization_id, left.metadata.sensor_info.initialization_id);
    ScanBatcher batcher(again.metadata.format);
    expect_complete_scans(receive_scans(again.lidar, batcher, 2, std::chrono::seconds(15), "127.0.0.3"), again.metadata,
                          2);

    SensorHttp right_http("127.0.0.4", daemon.port_of("127.0.0.4"));
    const httplib::Result bad = right_http.raw_post("/api/v1/sensor/config", R"({"lidar_mode": "4096x5"})");
    ASSERT_TRUE(bad);
    EXPECT_EQ(bad->status, 400) << bad->body;
    right_http.post("sensor/config?staging=true&reinit=true&persist=false", {{"operating_mode", "STANDBY"}});
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // a packet already on its way
    right.lidar.drain();
    EXPECT_FALSE(right.lidar.receive(std::chrono::milliseconds(500))) << "a sensor in STANDBY sends nothing";
  });
  std::vector<BatchedFrame> roof_scans =
      receive_scans(roof.lidar, roof_batcher, 8, std::chrono::seconds(20), "127.0.0.2");
  others.join();
  // One log for the rig: each sensor's lines name it.
  for (const auto& [name, address] : {std::pair{"roof", "127.0.0.2"}, {"left", "127.0.0.3"}, {"right", "127.0.0.4"}}) {
    EXPECT_NE(daemon.log().find(fmt::format("HTTP API ({}) on http://{}:", name, address)), std::string::npos);
    EXPECT_NE(daemon.log().find(fmt::format("faults ({}): none", name)), std::string::npos);
    EXPECT_NE(daemon.log().find(fmt::format("streamer ({}): lidar 512x10", name)), std::string::npos);
  }
  // and on past the right sensor's stop, the same stream: no gap at the join
  for (BatchedFrame& scan :
       receive_scans(roof.lidar, roof_batcher, 3, std::chrono::seconds(15), "127.0.0.2", /*joined_mid_frame=*/false)) {
    roof_scans.push_back(std::move(scan));
  }
  expect_complete_scans(roof_scans, roof.metadata, 11);
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

// A rig file's problems are refused before anything starts, naming the file, the sensor and the key.
struct BadRig {
  std::string name;
  std::string sensors;  // the "sensors" array's JSON
  std::string named;    // the message must contain this
  friend void PrintTo(const BadRig& rig, std::ostream* out) { *out << rig.name; }
};

class RigFile : public ::testing::TestWithParam<BadRig> {};

TEST_P(RigFile, IsRefusedNamingTheSensorAndTheKey) {
  const fs::path file = scratch_dir() / ("rig_" + GetParam().name + ".json");
  std::ofstream(file) << R"({"sensors": )" << GetParam().sensors << "}";
  std::string args;
  for (const std::string& arg : rig_args(file.string())) args += " '" + arg + "'";
  const auto [code, output] = run_cli("serve" + args);
  EXPECT_EQ(code, 2) << output;
  EXPECT_NE(output.find(file.string()), std::string::npos) << output;
  EXPECT_NE(output.find(GetParam().named), std::string::npos) << output;
  EXPECT_EQ(output.find("answering"), std::string::npos) << output;
}

INSTANTIATE_TEST_SUITE_P(
    Rigs, RigFile,
    ::testing::Values(
        BadRig{"same_address",
               R"([{"name": "a", "profile": "os0-32", "address": "127.0.0.2", "http_port": 8080},
                   {"name": "b", "profile": "os0-32", "address": "127.0.0.2", "http_port": 8080}])",
               "/sensors/1 (b)/address: 127.0.0.2:8080 is already sensor \"a\"'s"},
        BadRig{"bad_mode", R"([{"name": "left", "profile": "os0-32", "address": "127.0.0.3", "lidar_mode": "1000x7"}])",
               "/sensors/0 (left)/lidar_mode"},
        BadRig{"unknown_key", R"([{"name": "left", "profile": "os0-32", "address": "127.0.0.3", "adress": "x"}])",
               "adress"},
        BadRig{"no_profile", R"([{"name": "left", "address": "127.0.0.3"}])", "/sensors/0 (left)/profile"},
        BadRig{"unknown_profile", R"([{"name": "left", "profile": "os9-7", "address": "127.0.0.3"}])",
               "sensor \"left\": "},
        BadRig{"bad_mount", R"([{"name": "roof", "profile": "os0-32", "address": "127.0.0.3", "mount": [0, 0, 1]}])",
               "/sensors/0 (roof)/mount"},
        BadRig{"same_serial",
               R"([{"name": "a", "profile": "os0-32", "address": "127.0.0.2", "serial_number": "12"},
                   {"name": "b", "profile": "os0-32", "address": "127.0.0.3", "serial_number": "12"}])",
               "/sensors/1 (b)/serial_number"},
        BadRig{"bad_fault", R"([{"name": "a", "profile": "os0-32", "address": "127.0.0.2", "fault": "loss=2"}])",
               "sensor \"a\": "},
        BadRig{"no_sensors", "[]", "/sensors"}));

// The single-sensor flags belong in the rig file: given beside --rig, serve says so.
TEST(RigFlags, ASingleSensorFlagBesideARigIsRefused) {
  const auto [code, output] = run_cli("serve --rig " + kExampleRig + " --address 127.0.0.9 --http-port 0");
  EXPECT_NE(code, 0) << output;
  EXPECT_NE(output.find("--address"), std::string::npos) << output;
}

}  // namespace
}  // namespace lidartwin::e2e::rig_serve_test
