// SDK-1.0 SensorPacketSource (protocol doc 2.4 (d)): udp_dest probe, set_config, fetch_metadata,
// then reception that drops datagrams from any address but the sensor's and validates init_id and
// prod_sn on every packet.
#include <chrono>
#include <string>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e::sdk_packet_source_test {
namespace {

TEST(SensorPacketSource, ReceivesCompleteScansFromTheSensorsAddress) {
  UdpSocket lidar;
  UdpSocket imu;
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest options;  // the ports a user passes in the source options
  options.lidar_port = lidar.port();
  options.imu_port = imu.port();
  options.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk10_sensor_packet_source(http, options));
  // Step 6: the sockets are those of the fetched metadata.
  EXPECT_EQ(metadata.config_params.at("udp_port_lidar"), lidar.port());
  EXPECT_EQ(metadata.config_params.at("udp_port_imu"), imu.port());
  EXPECT_EQ(metadata.config_params.at("udp_dest"), "127.0.0.1");

  ScanBatcher batcher(metadata.format);
  const auto scans = receive_scans(lidar, batcher, 5, std::chrono::seconds(20), "127.0.0.1");
  expect_complete_scans(scans, metadata, 5);
  const auto imu_packet = imu.receive(std::chrono::seconds(2));
  ASSERT_TRUE(imu_packet);
  EXPECT_EQ(imu_packet->source_ip, "127.0.0.1");
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

// Column timestamps follow timestamp_mode (6.3): INTERNAL_OSC is time since boot (the host's
// CLOCK_MONOTONIC), PTP is TAI (CLOCK_REALTIME + 37 s).
TEST(SensorPacketSource, TimestampsFollowTheTimestampMode) {
  UdpSocket lidar;
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());
  for (const std::string mode : {"TIME_FROM_INTERNAL_OSC", "TIME_FROM_PTP_1588"}) {
    ConfigRequest options;
    options.lidar_port = lidar.port();
    options.timestamp_mode = mode;
    options.lidar_mode = "512x10";
    const Metadata metadata = parse(sdk10_sensor_packet_source(http, options));
    lidar.drain();
    ScanBatcher batcher(metadata.format);
    const auto scans = receive_scans(lidar, batcher, 2, std::chrono::seconds(10));
    expect_complete_scans(scans, metadata, 2);
    ASSERT_FALSE(scans.empty());
    const auto ts = static_cast<int64_t>(scans.back().scan.timestamp_ns.back());
    const int64_t expected =
        mode == "TIME_FROM_PTP_1588"
            ? std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
                      .count() +
                  37'000'000'000
            : monotonic_now_ns();
    EXPECT_NEAR(static_cast<double>(ts - expected) * 1e-9, 0.0, 1.0) << mode;
  }
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

}  // namespace
}  // namespace lidartwin::e2e::sdk_packet_source_test
