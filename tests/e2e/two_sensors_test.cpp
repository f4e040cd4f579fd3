// Several virtual sensors on one host, each on its own loopback address (DESIGN.md): each client
// gets only its sensor's packets, from its sensor's address (protocol doc 1 item 8). One test uses
// the real sensor port 80, which needs root (CI runs as root); it is skipped otherwise.
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e::two_sensors_test {
namespace {

struct Client {
  UdpSocket lidar;
  UdpSocket imu;
  Metadata metadata;
};

// Configures the sensor for the client with the SDK-1.0 sequence, then checks what arrives.
void connect(Daemon& daemon, Client& client) {
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest options;
  options.lidar_port = client.lidar.port();
  options.imu_port = client.imu.port();
  options.lidar_mode = "512x10";
  client.metadata = parse(sdk10_sensor_packet_source(http, options));
}

void expect_own_packets(Daemon& daemon, Client& client) {
  ScanBatcher batcher(client.metadata.format);
  expect_complete_scans(receive_scans(client.lidar, batcher, 3, std::chrono::seconds(15), daemon.address()),
                        client.metadata, 3);
  for (int i = 0; i < 5; ++i) {
    const auto datagram = client.imu.receive(std::chrono::seconds(2));
    ASSERT_TRUE(datagram);
    EXPECT_EQ(datagram->source_ip, daemon.address());
  }
}

void run_side_by_side(const std::string& a, const std::string& b, int http_port) {
  Daemon first(a, http_port, room_args());
  Daemon second(b, http_port, room_args());
  Client first_client;
  Client second_client;
  connect(first, first_client);
  connect(second, second_client);
  EXPECT_NE(first_client.metadata.sensor_info.prod_sn, second_client.metadata.sensor_info.prod_sn);
  expect_own_packets(first, first_client);
  expect_own_packets(second, second_client);
  EXPECT_EQ(first.stop(), 0) << first.log();
  EXPECT_EQ(second.stop(), 0) << second.log();
}

TEST(TwoSensors, RunSideBySideOnTheirOwnAddresses) { run_side_by_side("127.0.0.1", "127.0.0.2", 0); }

TEST(TwoSensors, RunSideBySideOnPort80AsRoot) {
  if (!running_as_root()) GTEST_SKIP() << "port 80 needs root (CI runs as root)";
  run_side_by_side("127.0.0.2", "127.0.0.3", 80);
}

// A port already taken is one clear line naming the address and port, and exit code 2.
TEST(TwoSensors, SecondSensorOnATakenPortExitsWithOneClearLine) {
  Daemon first("127.0.0.1", 0, room_args());
  std::string args = "serve --address 127.0.0.1 --http-port " + std::to_string(first.http_port());
  for (const auto& arg : room_args()) args += " '" + arg + "'";
  const auto [code, output] = run_cli(args);
  EXPECT_EQ(code, 2) << output;
  const std::string expected = "lidartwin: cannot serve HTTP on 127.0.0.1:" + std::to_string(first.http_port());
  EXPECT_NE(output.find(expected), std::string::npos) << output;
  EXPECT_EQ(first.stop(), 0) << first.log();
}

}  // namespace
}  // namespace lidartwin::e2e::two_sensors_test
