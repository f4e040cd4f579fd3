// Live poses as a HIL rig sends them: a simulator streams vehicle poses over UDP (or HTTP) while
// the daemon streams lidar packets; a client decodes the packets and deskews every point with its
// column timestamp and the pose it sent for that time. A wall must stay a wall while the sensor
// turns at 90 deg/s, and must not when every column is cast from its frame's first pose.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <thread>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/pose_sender.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "support/record_capture.h"
#include "support/test_scene.h"

namespace lidartwin::e2e {
namespace {

using nlohmann::json;

constexpr double kRateRadS = std::numbers::pi / 2;  // a 90 deg/s turn
constexpr double kSpeedMS = 0.5;                    // while creeping along x
constexpr double kHalfX = 4.0, kHalfY = 3.0, kHeight = 3.0;

// An empty 8 x 6 x 3 m room: every point the sensor sees lies on one of six known planes.
std::filesystem::path empty_room() {
  const auto path = scratch_dir() / "empty_room.glb";
  if (std::filesystem::exists(path)) return path;
  using test::quad;
  const float x0 = -4, x1 = 4, y0 = -3, y1 = 3, z0 = 0, z1 = 3;
  test::write_glb(path, {
                            quad("floor", {x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0}, 0.3f),
                            quad("ceiling", {x0, y0, z1}, {x0, y1, z1}, {x1, y1, z1}, {x1, y0, z1}, 0.6f),
                            quad("wall_north", {x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1}, 0.5f),
                            quad("wall_south", {x0, y0, z0}, {x0, y0, z1}, {x1, y0, z1}, {x1, y0, z0}, 0.5f),
                            quad("wall_east", {x1, y0, z0}, {x1, y0, z1}, {x1, y1, z1}, {x1, y1, z0}, 0.8f),
                            quad("wall_west", {x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, {x0, y0, z1}, 0.2f),
                        });
  return path;
}

double distance_to_room(const Eigen::Vector3d& p) {
  return std::min({std::abs(p.x() - kHalfX), std::abs(p.x() + kHalfX), std::abs(p.y() - kHalfY),
                   std::abs(p.y() + kHalfY), std::abs(p.z()), std::abs(p.z() - kHeight)});
}

int64_t monotonic_ns() { return monotonic_now_ns(); }

// The rig's motion, on CLOCK_MONOTONIC (the clock INTERNAL_OSC packets carry on this host).
struct Turn {
  int64_t t0_ns;
  RigPose at(int64_t time_ns, uint32_t sequence) const {
    const double t = static_cast<double>(time_ns - t0_ns) * 1e-9;
    RigPose pose;
    pose.sequence = sequence;
    pose.time_ns = time_ns;
    pose.position = {-0.75 + kSpeedMS * t, 0.0, 1.5};
    pose.orientation = Eigen::AngleAxisd(kRateRadS * t, Eigen::Vector3d::UnitZ());
    return pose;
  }
};

// Sends the turn at 200 Hz, stamped when sent; with `bad`, slips in one refused message of each
// kind every 10 messages (wrong size, unknown version, NaN, non-unit quaternion, time backwards).
class RigThread {
 public:
  RigThread(uint16_t port, Turn turn, bool bad) : sender_("127.0.0.1", port), thread_([=, this] { run(turn, bad); }) {}
  ~RigThread() {
    stop_ = true;
    thread_.join();
  }

 private:
  void run(Turn turn, bool bad) {
    uint32_t sequence = 0;
    while (!stop_) {
      const int64_t now = monotonic_ns();
      sender_.send(pose_datagram(turn.at(now, ++sequence)));
      if (bad && sequence % 10 == 0) send_bad(turn, now, sequence / 10 % 5);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  void send_bad(const Turn& turn, int64_t now, uint32_t kind) const {
    RigPose pose = turn.at(now, 0);
    switch (kind) {
      case 0: sender_.send(std::vector<uint8_t>(100, 0)); return;
      case 1: sender_.send(pose_datagram(pose, 9)); return;
      case 2: pose.position.y() = std::numeric_limits<double>::quiet_NaN(); break;
      case 3: pose.orientation.coeffs() *= 2.0; break;
      default: pose.time_ns = now - 1'000'000'000; break;
    }
    sender_.send(pose_datagram(pose));
  }

  PoseSender sender_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

struct LiveRun {
  std::vector<BatchedFrame> scans;
  Metadata metadata;
  test::SdkIntrinsics intrinsics;
  Turn turn;
  json pose_status;
  std::string log;
};

LiveRun fly(bool per_column_poses, bool bad_messages) {
  std::vector<std::string> args{"--profile",  "os1-32",      "--scene",      empty_room().string(),
                                "--threads",  "1",           "--seed",       "3",
                                "--pose-udp", "127.0.0.1:0", "--pose-clock", "monotonic"};
  if (!per_column_poses) args.push_back("--no-per-column-poses");
  Daemon daemon("127.0.0.1", 0, args);
  UdpSocket lidar;
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "1024x10";
  LiveRun run;
  const json metadata = sdk016_init_client(http, request);
  run.metadata = parse(metadata);
  const auto metadata_path = scratch_dir() / ("live_metadata_" + std::to_string(per_column_poses) + ".json");
  std::ofstream(metadata_path) << metadata.dump();
  run.intrinsics = test::SdkIntrinsics::load(metadata_path);
  run.turn = Turn{monotonic_ns()};
  {
    RigThread rig(pose_udp_port(daemon.log()), run.turn, bad_messages);
    std::this_thread::sleep_for(std::chrono::milliseconds(400));  // past the frames cast before poses came
    lidar.drain();
    ScanBatcher batcher(run.metadata.format);
    run.scans = receive_scans(lidar, batcher, 5, std::chrono::seconds(15));
    run.pose_status = json::parse(http.raw_get("/lidartwin/v1/pose")->body);
  }
  run.log = daemon.log();
  EXPECT_EQ(daemon.stop(), 0) << run.log;
  return run;
}

// Each valid point deskewed with its column's timestamp and the pose the rig sent for that time:
// its distance to the room's walls, floor and ceiling.
std::vector<double> deskewed_distances(const LiveRun& run) {
  std::vector<double> distances;
  for (const BatchedFrame& frame : run.scans) {
    const Scan& scan = frame.scan;
    for (int c = 0; c < scan.width; ++c) {
      if (!(scan.status[static_cast<size_t>(c)] & 1u)) continue;
      const RigPose pose = run.turn.at(static_cast<int64_t>(scan.timestamp_ns[static_cast<size_t>(c)]), 0);
      for (int r = 0; r < scan.height; ++r) {
        const uint32_t range_mm = scan.at(ChannelField::kRange, c, r);
        if (range_mm == 0) continue;
        const Eigen::Vector3d sensor_point = run.intrinsics.point(r, c, range_mm);
        distances.push_back(distance_to_room(pose.orientation * sensor_point + pose.position));
      }
    }
  }
  return distances;
}

double quantile(std::vector<double> values, double q) {
  const auto k = static_cast<size_t>(q * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

void print_distances(const char* what, const std::vector<double>& distances) {
  std::printf("%s: %zu points, distance to the walls median %.1f mm, p95 %.1f mm\n", what, distances.size(),
              quantile(distances, 0.5) * 1e3, quantile(distances, 0.95) * 1e3);
}

TEST(LivePoses, PointsStayOnTheWallsAfterDeskewingWhileTurningAt90DegPerSecond) {
  const LiveRun run = fly(true, true);
  expect_complete_scans(run.scans, run.metadata, 5);  // every column had a pose, bad messages or not
  const std::vector<double> distances = deskewed_distances(run);
  print_distances("per-column poses", distances);
  ASSERT_GT(distances.size(), 100'000u);
  // The profile's range noise is 1 cm (sigma) at these ranges: the median |error| is about 0.67 cm.
  EXPECT_LT(quantile(distances, 0.5), 0.012);
  EXPECT_LT(quantile(distances, 0.95), 0.035);

  const json& status = run.pose_status;
  EXPECT_GT(status["accepted"].get<int>(), 100);
  for (const char* reason : {"size", "version", "not_finite", "quaternion", "time_backwards"}) {
    EXPECT_GE(status["rejected"][reason].get<int>(), 1) << reason << "\n" << status.dump(2);
  }
  EXPECT_EQ(status["rejected"]["magic"].get<int>(), 0);
  EXPECT_EQ(status["lost"].get<int>(), 0);  // refused messages carry sequence 0, not a gap
  EXPECT_EQ(status["columns_without_pose"].get<int>(), 0) << status.dump(2);
  EXPECT_GT(status["latency"]["count"].get<int>(), 100);
  EXPECT_NE(run.log.find("live poses: refused pose message"), std::string::npos) << run.log;
}

TEST(LivePoses, WithoutPerColumnPosesTheWallsSmearAsTheSensorTurns) {
  const LiveRun run = fly(false, false);
  expect_complete_scans(run.scans, run.metadata, 5);
  const std::vector<double> distances = deskewed_distances(run);
  print_distances("frame poses", distances);
  ASSERT_GT(distances.size(), 100'000u);
  // Up to 9 degrees of turn between a frame's first and last column: decimetres off the walls.
  EXPECT_GT(quantile(distances, 0.5), 0.05);
  EXPECT_GT(quantile(distances, 0.95), 0.25);
}

}  // namespace
}  // namespace lidartwin::e2e
