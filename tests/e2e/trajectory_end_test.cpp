// What the end of a served trajectory means (serve --trajectory-end), as a client sees it in the
// ranges: an open trajectory holds its last pose unless told to loop or stop, a closed one loops,
// and "stop" ends both streams after the last frame that began before the end. Short trajectories
// in the room, noise-free, so a frame's range ahead says where the sensor was.
#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "e2e/support/moving_room.h"

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e::trajectory_end_test {
namespace {

struct Stream {
  Received received;
  Metadata metadata;
  std::string log;
};

// Starts the daemon, configures 512x10 to this test's sockets, and listens for `listen`.
Stream stream(const std::vector<std::string>& args, std::chrono::milliseconds listen) {
  UdpSocket lidar;
  UdpSocket imu;
  Daemon daemon("127.0.0.1", 0, args);
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  request.lidar_mode = "512x10";
  Stream out;
  out.metadata = parse(sdk016_init_client(http, request));
  out.received = receive_for(lidar, imu, out.metadata, listen);
  out.log = daemon.log();
  return out;
}

// Where the sensor was at the start of each frame received whole.
std::vector<double> frame_start_xs(const Stream& s) {
  std::vector<double> xs;
  for (const auto& [id, frame] : s.received.frames) {
    const bool whole =
        std::all_of(frame.packet_received.begin(), frame.packet_received.end(), [](uint64_t n) { return n != 0; });
    if (whole) xs.push_back(x_at_frame_start(frame));
  }
  return xs;
}

double spread(const std::vector<double>& xs) {
  const auto [low, high] = std::minmax_element(xs.begin(), xs.end());
  return *high - *low;
}

// x from -1 to +1 in 0.2 s: over before the configured stream's first frame (a quarter second
// after the client's reinit), and two frames long, so looping shows frames 1 m apart.
std::filesystem::path open_trajectory() { return write_x_trajectory("open", {0.0, 0.2}, {-1.0, 1.0}); }

TEST(TrajectoryEnd, AnOpenTrajectoryHoldsItsLastPoseByDefault) {
  const Stream s = stream(moving_room_args(open_trajectory()), std::chrono::milliseconds(800));
  const std::vector<double> xs = frame_start_xs(s);
  ASSERT_GE(xs.size(), 4u) << s.log;
  for (const double x : xs) EXPECT_NEAR(x, 1.0, 0.03);
  EXPECT_EQ(spread(xs), 0.0);  // not a millimetre: the pose is held exactly
  EXPECT_NE(s.log.find("at its end it holds its last pose (it does not close: its last pose is 2.000 m"),
            std::string::npos)
      << s.log;
}

TEST(TrajectoryEnd, LoopRepeatsAnOpenTrajectoryWhenAskedTo) {
  auto args = moving_room_args(open_trajectory());
  args.insert(args.end(), {"--trajectory-end", "loop"});
  const Stream s = stream(args, std::chrono::milliseconds(800));
  const std::vector<double> xs = frame_start_xs(s);
  ASSERT_GE(xs.size(), 4u) << s.log;
  EXPECT_GT(spread(xs), 0.5);  // frames a half period apart: 1 m
  EXPECT_NE(s.log.find("at its end it loops (--trajectory-end loop"), std::string::npos) << s.log;
}

// -1 -> +1 -> -1 in 0.3 s: it closes, so it loops, and frames 0.1 s apart see it 0.67-1.33 m apart.
TEST(TrajectoryEnd, AClosedTrajectoryLoopsByDefault) {
  const auto closed = write_x_trajectory("closed", {0.0, 0.15, 0.3}, {-1.0, 1.0, -1.0});
  const Stream s = stream(moving_room_args(closed), std::chrono::milliseconds(800));
  const std::vector<double> xs = frame_start_xs(s);
  ASSERT_GE(xs.size(), 4u) << s.log;
  EXPECT_GT(spread(xs), 0.5);
  EXPECT_NE(s.log.find("at its end it loops (it closes: its last pose is 0.000 m and 0.00 deg from its first"),
            std::string::npos)
      << s.log;
}

// With the motion starting at frame 0 of the configured stream (--motion-start configured), a
// 0.45 s trajectory at 10 Hz begins frames 0-4 (0.4 s < 0.45 s): those five are sent whole, then
// nothing, lidar or IMU (IMU samples of those 0.5 s: 50).
TEST(TrajectoryEnd, StopEndsBothStreamsAfterTheLastFrameThatBeganBeforeTheEnd) {
  const auto short_flight = write_x_trajectory("short", {0.0, 0.45}, {-1.0, 1.0});
  auto args = moving_room_args(short_flight);
  args.insert(args.end(), {"--trajectory-end", "stop", "--motion-start", "configured"});
  const Stream s = stream(args, std::chrono::milliseconds(1500));
  const size_t packets_per_frame = static_cast<size_t>(PacketFormat(s.metadata.format).packets_per_frame());
  EXPECT_EQ(s.received.lidar_packets, 5 * packets_per_frame) << s.log;
  EXPECT_EQ(frame_start_xs(s).size(), 5u);
  EXPECT_EQ(s.received.imu_packets, 50u);
  EXPECT_NE(s.log.find("streaming stopped"), std::string::npos) << s.log;
}

TEST(TrajectoryEnd, BadValuesAreRefusedNamingTheFlag) {
  const std::string base = "serve --http-port 0 --profile os1-32 --threads 1 --scene '" + room_scene().string() +
                           "' --trajectory '" + open_trajectory().string() + "' ";
  const auto [end_code, end_output] = run_cli(base + "--trajectory-end sometimes");
  EXPECT_NE(end_code, 0);
  EXPECT_NE(end_output.find("--trajectory-end sometimes: must be hold, loop or stop"), std::string::npos) << end_output;
  const auto [start_code, start_output] = run_cli(base + "--motion-start later");
  EXPECT_NE(start_code, 0);
  EXPECT_NE(start_output.find("--motion-start later: must be daemon or configured"), std::string::npos) << start_output;
}

}  // namespace
}  // namespace lidartwin::e2e::trajectory_end_test
