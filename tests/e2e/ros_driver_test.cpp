// ouster-ros (protocol doc 2.4 (e)): start-up with two set_config rounds, then the set_config
// service changing lidar_mode mid-stream. After the reinit the packets carry a new init_id and the
// new size and count, and scans assemble completely again after the driver's reset.
#include <chrono>
#include <string>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e::ros_driver_test {
namespace {

// What the driver's poll loop sees until the first packet of a different length (6 in 2.4 (e)).
size_t packets_until_size_changes(UdpSocket& lidar, size_t old_size, std::chrono::seconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto datagram = lidar.receive(std::chrono::milliseconds(500));
    if (datagram && datagram->bytes.size() != old_size) return datagram->bytes.size();
  }
  return old_size;
}

TEST(RosDriver, ReinitWithANewLidarModeRestartsTheStream) {
  UdpSocket lidar;
  UdpSocket imu;
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());

  const Metadata before = parse(ros_driver_start(http, "512x10", lidar.port(), imu.port()));
  ScanBatcher first(before.format);
  expect_complete_scans(receive_scans(lidar, first, 3, std::chrono::seconds(15), "127.0.0.1"), before, 3);

  // The set_config service: sequence (a) with FORCE_REINIT, then a reset (the whole start-up).
  ConfigRequest change;
  change.lidar_mode = "1024x10";
  change.udp_profile_lidar = "RNG15_RFL8_NIR8";
  change.force_reinit = true;
  set_config(http, change);
  const size_t new_size =
      packets_until_size_changes(lidar, first.format().lidar_packet_size(), std::chrono::seconds(5));
  EXPECT_NE(new_size, first.format().lidar_packet_size()) << "the stream did not change format";

  const Metadata after = parse(ros_driver_start(http, "1024x10", lidar.port(), imu.port()));
  EXPECT_NE(after.sensor_info.initialization_id, before.sensor_info.initialization_id);
  EXPECT_EQ(after.format.columns_per_frame, 1024);
  ScanBatcher second(after.format);
  EXPECT_EQ(second.format().lidar_packet_size(), new_size);
  EXPECT_EQ(second.expected_packets(), 64u);
  expect_complete_scans(receive_scans(lidar, second, 3, std::chrono::seconds(15), "127.0.0.1"), after, 3);
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

}  // namespace
}  // namespace lidartwin::e2e::ros_driver_test
