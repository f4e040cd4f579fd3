// serve --motion-start configured: a trajectory waits, holding its first pose, until a client
// first configures the sensor, so a driver that connects late still sees the motion from its
// start. A reinit starts it with frame 0 of the stream it configured; a client that never
// reinitializes starts it by reading sensor/metadata, at a frame boundary soon after.
#include <algorithm>
#include <chrono>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "e2e/support/moving_room.h"

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e::motion_start_test {
namespace {

// x from -1 to +1 in 0.45 s; frames 0.1 s apart see it 0.44 m apart.
std::vector<std::string> waiting_args() {
  auto args = moving_room_args(write_x_trajectory("flight", {0.0, 0.45}, {-1.0, 1.0}));
  args.insert(args.end(), {"--motion-start", "configured"});
  return args;
}

std::vector<double> xs_in_frame_order(const Received& received) {
  std::vector<double> xs;
  for (const auto& [id, frame] : received.frames) {
    if (frame.packet_received.front() != 0) xs.push_back(x_at_frame_start(frame));  // column 0 arrived
  }
  return xs;
}

TEST(MotionStart, AReinitStartsTheTrajectoryWithFrameZeroOfTheConfiguredStream) {
  UdpSocket lidar;
  UdpSocket imu;
  Daemon daemon("127.0.0.1", 0, waiting_args());
  std::this_thread::sleep_for(std::chrono::seconds(1));  // a client that comes late: the flight takes 0.45 s
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  const Received received = receive_for(lidar, imu, metadata, std::chrono::milliseconds(1000));
  // frame_id restarts at the reinit (6.2): frame 0 is the configured stream's first.
  ASSERT_TRUE(received.frames.contains(0)) << daemon.log();
  ASSERT_TRUE(received.frames.contains(2)) << daemon.log();
  ASSERT_TRUE(received.frames.contains(6)) << daemon.log();
  EXPECT_NEAR(x_at_frame_start(received.frames.at(0)), -1.0, 0.03);
  EXPECT_NEAR(x_at_frame_start(received.frames.at(2)), -1.0 + 2.0 * 0.2 / 0.45, 0.03);
  EXPECT_NEAR(x_at_frame_start(received.frames.at(6)), 1.0, 0.03);  // over, held
  EXPECT_NE(daemon.log().find("the motion starts with frame 0 of its stream"), std::string::npos) << daemon.log();
}

// SDK 1.0's SensorPacketSource leaves a sensor whose config already suits it alone (protocol doc
// 2.4 (d)): here the saved config streams to this test's sockets, and the client only reads.
TEST(MotionStart, AClientThatNeverReinitializesStartsItByReadingTheMetadata) {
  UdpSocket lidar;
  UdpSocket imu;
  const auto state = scratch_dir() / "motion_start_state.json";
  std::ofstream(state)
      << nlohmann::json{{"lidartwin_state", 1},
                        {"config",
                         {{"udp_port_lidar", lidar.port()}, {"udp_port_imu", imu.port()}, {"lidar_mode", "512x10"}}}}
             .dump();
  auto args = waiting_args();
  args.insert(args.end(), {"--state-file", state.string()});
  Daemon daemon("127.0.0.1", 0, args);
  SensorHttp http(daemon.address(), daemon.http_port());
  // The packets' format from the metadata's sections, which do not count as reading the metadata.
  nlohmann::json sections;
  for (const char* name : {"sensor_info", "beam_intrinsics", "imu_intrinsics", "lidar_intrinsics", "lidar_data_format",
                           "calibration_status", "config_params", "imu_data_format"}) {
    sections[name] = http.get_json(std::string("sensor/metadata/") + name);
  }
  const Metadata metadata = parse(sections);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));  // the flight would be over by now
  const Received before = receive_for(lidar, imu, metadata, std::chrono::milliseconds(400));
  ASSERT_GE(before.frames.size(), 3u) << daemon.log();
  const std::vector<double> held = xs_in_frame_order(before);
  ASSERT_FALSE(held.empty());
  EXPECT_NEAR(held.front(), -1.0, 0.03);
  for (const double x : held) EXPECT_EQ(x, held.front());  // held at the first pose, to the millimetre

  http.get("sensor/metadata");
  const Received after = receive_for(lidar, imu, metadata, std::chrono::milliseconds(1200));
  const std::vector<double> xs = xs_in_frame_order(after);
  ASSERT_GE(xs.size(), 8u) << daemon.log();
  // Held, then the flight from its start at a frame boundary (its frame 0.1 s in shows x = -0.56),
  // then held at its end; never a step back.
  const auto moved = std::find_if(xs.begin(), xs.end(), [&](double x) { return x != held.front(); });
  ASSERT_NE(moved, xs.end()) << daemon.log();
  EXPECT_NE(moved, xs.begin()) << "the motion started before the metadata was read";
  EXPECT_NEAR(*moved, -1.0 + 2.0 * 0.1 / 0.45, 0.03);
  EXPECT_TRUE(std::is_sorted(xs.begin(), xs.end()));
  EXPECT_NEAR(xs.back(), 1.0, 0.03);
  EXPECT_NE(daemon.log().find("a client read " + metadata.sensor_info.prod_sn + "'s metadata: the motion starts"),
            std::string::npos)
      << daemon.log();
}

}  // namespace
}  // namespace lidartwin::e2e::motion_start_test
