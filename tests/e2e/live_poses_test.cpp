// Live poses as a HIL rig sends them: a simulator streams vehicle poses over UDP (or HTTP) while
// the daemon streams lidar packets; a client decodes the packets and deskews every point with its
// column timestamp and the pose it sent for that time. A wall must stay a wall while the sensor
// turns at 90 deg/s, and must not when every column is cast from its frame's first pose.
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <numbers>
#include <optional>
#include <thread>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/pose_sender.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/pose/pose_message.h"
#include "support/record_capture.h"
#include "support/test_scene.h"

namespace lidartwin::e2e::live_poses_test {
namespace {

using nlohmann::json;

constexpr double kRateRadS = std::numbers::pi / 2;  // a 90 deg/s turn
constexpr double kSpeedMS = 0.5;                    // while creeping along x
constexpr double kHalfX = 4.0, kHalfY = 3.0, kHeight = 3.0;

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

// A client configures 1024x10 to `lidar` and reads the metadata and the beams' intrinsics as the SDK
// would (from a file named `name`).
struct Configured {
  Metadata metadata;
  test::SdkIntrinsics intrinsics;
};
Configured configure_1024x10(SensorHttp& http, const UdpSocket& lidar, const std::string& name) {
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "1024x10";
  const json metadata = sdk016_init_client(http, request);
  const auto metadata_path = scratch_dir() / (name + ".json");
  std::ofstream(metadata_path) << metadata.dump();
  return {parse(metadata), test::SdkIntrinsics::load(metadata_path)};
}

LiveRun fly(bool per_column_poses, bool bad_messages) {
  std::vector<std::string> args{"--profile",  "os1-32",      "--scene",      empty_room_scene().string(),
                                "--threads",  "1",           "--seed",       "3",
                                "--pose-udp", "127.0.0.1:0", "--pose-clock", "monotonic"};
  if (!per_column_poses) args.push_back("--no-per-column-poses");
  Daemon daemon("127.0.0.1", 0, args);
  UdpSocket lidar;
  std::optional<SensorHttp> client(std::in_place, daemon.address(), daemon.http_port());
  SensorHttp& http = *client;
  LiveRun run;
  Configured configured = configure_1024x10(http, lidar, "live_metadata_" + std::to_string(per_column_poses));
  run.metadata = std::move(configured.metadata);
  run.intrinsics = std::move(configured.intrinsics);
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
  client.reset();  // closes the keep-alive connection, so the daemon stops at once
  EXPECT_EQ(daemon.stop(), 0) << run.log;
  return run;
}

// Every packet of every scan arrived (the stream went on), and nearly every column was cast in time:
// a loaded host may leave a packet uncast by its deadline, which then goes out invalid, on time.
void expect_whole_scans(const LiveRun& run) {
  ASSERT_EQ(run.scans.size(), 5u);
  size_t valid = 0, columns = 0;
  for (size_t i = 0; i < run.scans.size(); ++i) {
    const BatchedFrame& frame = run.scans[i];
    EXPECT_TRUE(frame.complete) << "frame " << frame.frame_id << ": " << frame.packets << " packets";
    if (i > 0) {
      EXPECT_EQ(frame.frame_id, run.scans[i - 1].frame_id + 1);
    }
    for (uint32_t status : frame.scan.status) valid += status & 1u;
    columns += frame.scan.status.size();
  }
  EXPECT_GT(static_cast<double>(valid), 0.95 * static_cast<double>(columns));
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
  expect_whole_scans(run);  // bad messages or not
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
  // One latency sample per pose revision a sent packet first carried: the renderer casts packets in
  // batches, so on a loaded host several of the 200 Hz poses fall into one batch and count once.
  EXPECT_GT(status["latency"]["count"].get<int>(), 25);
  EXPECT_LE(status["latency"]["count"].get<int>(), status["accepted"].get<int>());
  EXPECT_NE(run.log.find("live poses: refused pose message"), std::string::npos) << run.log;
}

TEST(LivePoses, WithoutPerColumnPosesTheWallsSmearAsTheSensorTurns) {
  const LiveRun run = fly(false, false);
  expect_whole_scans(run);
  const std::vector<double> distances = deskewed_distances(run);
  print_distances("frame poses", distances);
  ASSERT_GT(distances.size(), 100'000u);
  // Up to 9 degrees of turn between a frame's first and last column: decimetres off the walls.
  EXPECT_GT(quantile(distances, 0.5), 0.05);
  EXPECT_GT(quantile(distances, 0.95), 0.25);
}

// The rig holds the sensor still at `before`, then moves it to `after` at once (a teleport: no
// velocity, so no extrapolation smears the change), sending poses every 5 ms with zero velocity.
class JumpRig {
 public:
  JumpRig(uint16_t port, Eigen::Vector3d before, Eigen::Vector3d after, int64_t jump_ns)
      : sender_("127.0.0.1", port), thread_([=, this] { run(before, after, jump_ns); }) {}
  ~JumpRig() {
    stop_ = true;
    thread_.join();
  }
  // The time_ns of the first pose sent at `after` (0 until it is sent).
  int64_t jumped_ns() const { return jumped_ns_.load(); }

 private:
  void run(const Eigen::Vector3d& before, const Eigen::Vector3d& after, int64_t jump_ns) {
    for (uint32_t sequence = 1; !stop_; ++sequence) {
      PoseMessage message;
      message.sequence = sequence;
      message.time_ns = monotonic_ns();
      const bool jumped = message.time_ns >= jump_ns;
      message.pose.translation = jumped ? after : before;
      message.velocity = Eigen::Vector3d::Zero();
      message.angular_rate = Eigen::Vector3d::Zero();
      const auto bytes = encode_pose_message(message);
      sender_.send(std::vector<uint8_t>(bytes.begin(), bytes.end()));
      if (jumped && jumped_ns_.load() == 0) jumped_ns_ = message.time_ns;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }

  PoseSender sender_;
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> jumped_ns_{0};
  std::thread thread_;
};

// Which of two sensor positions a column's returns fit (within 3 cm of the room), counting only the
// returns that fit one and not the other (the floor fits both when the sensor moves sideways).
enum class Fit { kNeither, kBefore, kAfter };
Fit column_fit(const Scan& scan, int c, const test::SdkIntrinsics& intrinsics, const Eigen::Vector3d& before,
               const Eigen::Vector3d& after) {
  int only_before = 0, only_after = 0;
  for (int r = 0; r < scan.height; ++r) {
    const uint32_t range_mm = scan.at(ChannelField::kRange, c, r);
    if (range_mm == 0) continue;
    const Eigen::Vector3d point = intrinsics.point(r, c, range_mm);
    const bool fits_before = distance_to_room(point + before) < 0.03;
    const bool fits_after = distance_to_room(point + after) < 0.03;
    only_before += fits_before && !fits_after;
    only_after += fits_after && !fits_before;
  }
  if (only_before >= 3 && only_before > 2 * only_after) return Fit::kBefore;
  if (only_after >= 3 && only_after > 2 * only_before) return Fit::kAfter;
  return Fit::kNeither;
}

// --cast-ahead-ms 50 (what a busy host needs): every packet is cast 50 ms before it is due, so
// without casting again the sensor would be seen where it was 50 ms before. A pose arriving after a
// packet was cast must still reach it: the packets due 8-45 ms after the sensor jumped show it
// where it jumped to (all of them would show the old place if packets were cast only once).
TEST(LivePoses, APoseArrivingAfterAPacketWasCastReachesItBeforeItIsSent) {
  Daemon daemon("127.0.0.1", 0,
                {"--profile", "os1-32", "--scene", empty_room_scene().string(), "--threads", "1", "--seed", "3",
                 "--pose-udp", "127.0.0.1:0", "--pose-clock", "monotonic", "--cast-ahead-ms", "50"});
  UdpSocket lidar;
  std::optional<SensorHttp> client(std::in_place, daemon.address(), daemon.http_port());
  SensorHttp& http = *client;
  const auto [metadata, intrinsics] = configure_1024x10(http, lidar, "jump_metadata");
  const Eigen::Vector3d before(-2.0, 0.0, 1.5), after(1.5, 1.0, 1.5);
  std::vector<BatchedFrame> scans;
  int64_t jumped_ns = 0;
  {
    // The jump 0.6 s after the scans begin, so that a test thread held up on a loaded host still
    // sees the sensor at the old place first.
    JumpRig rig(pose_udp_port(daemon.log()), before, after, monotonic_ns() + 1'500'000'000);
    std::this_thread::sleep_for(std::chrono::milliseconds(900));
    lidar.drain();
    ScanBatcher batcher(metadata.format);
    scans = receive_scans(lidar, batcher, 9, std::chrono::seconds(15));
    jumped_ns = rig.jumped_ns();
  }
  ASSERT_EQ(scans.size(), 9u);
  ASSERT_NE(jumped_ns, 0);
  // Columns by their time after the jump: well before, in the window cast before the jump, after it.
  std::array<std::array<int, 3>, 3> counts{};  // [earlier / window / later][neither, before, after]
  for (const BatchedFrame& frame : scans) {
    for (int c = 0; c < frame.scan.width; ++c) {
      if (!(frame.scan.status[static_cast<size_t>(c)] & 1u)) continue;
      const int64_t since_ms =
          (static_cast<int64_t>(frame.scan.timestamp_ns[static_cast<size_t>(c)]) - jumped_ns) / 1'000'000;
      const int when = since_ms < -10 ? 0 : since_ms >= 8 && since_ms < 45 ? 1 : since_ms >= 60 ? 2 : -1;
      if (when < 0) continue;
      ++counts[static_cast<size_t>(when)][static_cast<size_t>(column_fit(frame.scan, c, intrinsics, before, after))];
    }
  }
  const auto share = [&counts](size_t when, Fit fit) {
    const auto& row = counts[when];
    return static_cast<double>(row[static_cast<size_t>(fit)]) / std::max(1, row[0] + row[1] + row[2]);
  };
  std::printf("columns seen from the old / new place: before the jump %d / %d, 8-45 ms after %d / %d, later %d / %d\n",
              counts[0][1], counts[0][2], counts[1][1], counts[1][2], counts[2][1], counts[2][2]);
  // The classification itself: the columns long before and after show where the rig said.
  EXPECT_GT(counts[0][1], 1000);
  EXPECT_GT(share(0, Fit::kBefore), 0.95);
  EXPECT_GT(counts[2][2], 1000);
  EXPECT_GT(share(2, Fit::kAfter), 0.95);
  // The window: about 380 columns, all cast 50 ms ahead with the old place; most cast again.
  EXPECT_GT(counts[1][0] + counts[1][1] + counts[1][2], 300);
  EXPECT_GT(share(1, Fit::kAfter), 0.5);
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // the streamer's stats are once a second
  const json status = json::parse(http.raw_get("/lidartwin/v1/pose")->body);
  EXPECT_GT(status["recast_packets"].get<int>(), 0) << status.dump(2);
  client.reset();  // closes the keep-alive connection, so the daemon stops at once
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

json pose_json(uint32_t sequence, int64_t time_ns, double qw = 1.0) {
  return {{"sequence", sequence},
          {"time_ns", time_ns},
          {"position", {1.0, 0.5, 1.5}},
          {"orientation", {0.0, 0.0, 0.0, qw}},
          {"velocity", {0.2, 0.0, 0.0}}};
}

TEST(LivePosesHttp, PostedPosesAreTakenAndBadOnesRefusedWithTheReason) {
  Daemon daemon("127.0.0.1", 0,
                {"--profile", "os1-32", "--scene", empty_room_scene().string(), "--threads", "1", "--live-poses"});
  std::optional<SensorHttp> client(std::in_place, daemon.address(), daemon.http_port());
  SensorHttp& http = *client;
  const int64_t now = monotonic_ns();
  auto ok = http.raw_post("/lidartwin/v1/pose", pose_json(1, now).dump());
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200) << ok->body;
  EXPECT_EQ(json::parse(ok->body)["sequence"], 1);

  const auto refused = [&http](const std::string& body) {
    auto response = http.raw_post("/lidartwin/v1/pose", body);
    EXPECT_EQ(response->status, 400) << body;
    return json::parse(response->body);
  };
  const json quaternion = refused(pose_json(2, now + 10'000'000, 1.5).dump());
  EXPECT_EQ(quaternion["rejected"], "quaternion");
  EXPECT_NE(quaternion["error"].get<std::string>().find("unit quaternion"), std::string::npos);
  EXPECT_EQ(refused(pose_json(3, now - 10'000'000).dump())["rejected"], "time_backwards");
  EXPECT_EQ(refused("{\"sequence\": 4")["rejected"], "malformed");
  json misspelt = pose_json(5, now + 20'000'000);
  misspelt["postion"] = misspelt["position"];
  const json unknown = refused(misspelt.dump());
  EXPECT_EQ(unknown["rejected"], "malformed");
  EXPECT_NE(unknown["error"].get<std::string>().find("postion"), std::string::npos) << unknown.dump();

  const json status = json::parse(http.raw_get("/lidartwin/v1/pose")->body);
  EXPECT_EQ(status["accepted"], 1);
  EXPECT_EQ(status["rejected"]["quaternion"], 1);
  EXPECT_EQ(status["rejected"]["time_backwards"], 1);
  EXPECT_EQ(status["rejected"]["malformed"], 2);
  EXPECT_EQ(status["newest"]["sequence"], 1);
  EXPECT_EQ(status["newest"]["velocity"], json({0.2, 0.0, 0.0}));
  EXPECT_EQ(http.raw_get("/lidartwin/v1/nothing")->status, 404);
  EXPECT_EQ(http.raw_get("/api/v1/sensor/metadata/sensor_info")->status, 200);  // the sensor's API is untouched
  client.reset();  // closes the keep-alive connection, so the daemon stops at once
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

TEST(LivePosesHttp, ADaemonFlyingATrajectoryHasNoPoseEndpoint) {
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());
  EXPECT_EQ(http.raw_post("/lidartwin/v1/pose", pose_json(1, 1).dump())->status, 404);
}

// Two complete scans in a row among the first eight while poses come. (Not the first two: on a
// loaded host the test's own pose sender can fall more than --pose-extrapolate-ms behind, and
// "standby" then rightly withholds those packets; a daemon that never resumed sends none whole.)
void expect_complete_scans_in_a_row(UdpSocket& lidar, ScanBatcher& batcher) {
  std::string seen;  // packets per scan, for the message
  int in_a_row = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  for (int k = 0; k < 8 && in_a_row < 2 && std::chrono::steady_clock::now() < deadline; ++k) {
    const auto scans = receive_scans(lidar, batcher, 1, std::chrono::seconds(5), "", k == 0);
    if (scans.empty()) break;
    in_a_row = scans.front().complete ? in_a_row + 1 : 0;
    seen += std::to_string(scans.front().packets) + " ";
  }
  EXPECT_EQ(in_a_row, 2) << "packets per scan: " << seen;
}

// Timeout policy "standby": no lidar packet goes out until poses come, none once they stop, and
// complete scans again once they resume.
TEST(LivePosesTimeout, StandbySendsNothingWithoutPosesAndResumesWithThem) {
  Daemon daemon("127.0.0.1", 0,
                {"--profile", "os1-32", "--scene", empty_room_scene().string(), "--threads", "1", "--pose-udp",
                 "127.0.0.1:0", "--pose-clock", "monotonic", "--pose-timeout", "standby", "--pose-extrapolate-ms",
                 "100", "--cast-ahead-ms", "20"});
  UdpSocket lidar;
  std::optional<SensorHttp> client(std::in_place, daemon.address(), daemon.http_port());
  SensorHttp& http = *client;
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  EXPECT_FALSE(lidar.receive(std::chrono::milliseconds(600))) << "a packet without any pose";
  {
    RigThread rig(pose_udp_port(daemon.log()), Turn{monotonic_ns()}, false);
    ScanBatcher batcher(metadata.format);
    expect_complete_scans_in_a_row(lidar, batcher);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the stream stalls
  lidar.drain();
  EXPECT_FALSE(lidar.receive(std::chrono::milliseconds(500))) << "a packet after the poses stopped";
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // the streamer's stats are once a second
  const json status = json::parse(http.raw_get("/lidartwin/v1/pose")->body);
  EXPECT_GT(status["withheld_packets"].get<int>(), 0) << status.dump(2);
  EXPECT_TRUE(status["stalled"].get<bool>());
  {
    // The pose source resumes (issue 27: stalls and resumes): so do complete scans, and the stall
    // is over.
    RigThread rig(pose_udp_port(daemon.log()), Turn{monotonic_ns()}, false);
    ScanBatcher batcher(metadata.format);
    expect_complete_scans_in_a_row(lidar, batcher);
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));
    const json resumed = json::parse(http.raw_get("/lidartwin/v1/pose")->body);
    EXPECT_FALSE(resumed["stalled"].get<bool>()) << resumed.dump(2);
  }
  client.reset();  // closes the keep-alive connection, so the daemon stops at once
  EXPECT_EQ(daemon.stop(), 0);
  EXPECT_NE(daemon.log().find("live poses: stream stalled"), std::string::npos) << daemon.log();
}

// --stamp-pose-clock: paced on this host's clock but stamped on the poses' own clock (a simulator's,
// here 1000 s ahead of CLOCK_MONOTONIC): nothing goes out before the first pose tells the clock.
TEST(LivePosesClock, PacketsCarryThePosesClockWhenAsked) {
  constexpr int64_t kAhead = 1'000'000'000'000;
  Daemon daemon("127.0.0.1", 0,
                {"--profile", "os1-32", "--scene", empty_room_scene().string(), "--threads", "1", "--pose-udp",
                 "127.0.0.1:0", "--stamp-pose-clock", "--cast-ahead-ms", "20"});
  UdpSocket lidar;
  std::optional<SensorHttp> client(std::in_place, daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(*client, request));
  EXPECT_FALSE(lidar.receive(std::chrono::milliseconds(400))) << "a packet before the poses' clock was known";
  std::atomic<bool> done{false};
  std::thread rig([&] {
    PoseSender sender("127.0.0.1", pose_udp_port(daemon.log()));
    const Turn turn{monotonic_ns()};
    for (uint32_t sequence = 1; !done; ++sequence) {
      RigPose pose = turn.at(monotonic_ns(), sequence);
      pose.time_ns += kAhead;
      sender.send(pose_datagram(pose));
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  ScanBatcher batcher(metadata.format);
  size_t scans = 0;
  while (scans < 3) {
    const auto d = lidar.receive(std::chrono::seconds(5));
    ASSERT_TRUE(d) << "no packet after the poses came";
    const auto scan = batcher.add(d->bytes);
    if (!scan) continue;
    ++scans;
    // Released when the next frame's first packet came: its last column was stamped just before.
    uint64_t last = 0;
    for (size_t m = 0; m < scan->scan.status.size(); ++m) {
      if (scan->scan.status[m] & 1u) last = std::max(last, scan->scan.timestamp_ns[m]);
    }
    EXPECT_NEAR(static_cast<double>(static_cast<int64_t>(last) - (d->received_ns + kAhead)) * 1e-9, 0.0, 0.03);
  }
  // The sensor's time is the packets' clock too (time/sensor, in every timestamp mode).
  const json time = client->get_json("time/sensor").at("timestamp");
  const double expected_s = static_cast<double>(monotonic_ns() + kAhead) * 1e-9;
  EXPECT_NEAR(time.at("time").get<double>(), expected_s, 0.05) << time.dump();
  EXPECT_NEAR(time.at("time_options").at("ptp_1588").get<double>(), expected_s, 0.05) << time.dump();
  done = true;
  rig.join();
  client.reset();
  EXPECT_EQ(daemon.stop(), 0);
}

// Lock-step: the simulator's clock drives the sensor. Poses stamped in simulation time arrive at
// `speed` times real time; every packet stamped up to the newest simulation time must come, in
// order, stamped exactly on the simulation's clock.
class LockStep : public ::testing::TestWithParam<double> {};

TEST_P(LockStep, FramesFollowTheSimulationClockExactlyAtAnySpeed) {
  const double speed = GetParam();
  Daemon daemon("127.0.0.1", 0,
                {"--profile", "os1-32", "--scene", empty_room_scene().string(), "--threads", "1", "--pose-udp",
                 "127.0.0.1:0", "--lock-step"});
  UdpSocket lidar;
  UdpSocket imu;
  std::optional<SensorHttp> client(std::in_place, daemon.address(), daemon.http_port());
  SensorHttp& http = *client;
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  request.lidar_mode = "1024x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  EXPECT_FALSE(lidar.receive(std::chrono::milliseconds(300))) << "a packet before the simulation's time began";

  constexpr int64_t kSimStart = 5'000'000'000;  // simulation time of the first pose
  constexpr int64_t kStep = 10'000'000;         // 10 ms of simulation per pose
  constexpr int kPoses = 81;                    // 0.8 s of simulation: 8 frames
  const int64_t sim_end = kSimStart + (kPoses - 1) * kStep;
  std::vector<Datagram> lidar_datagrams;
  std::vector<Datagram> imu_datagrams;
  {
    std::atomic<bool> done{false};
    std::thread receiver([&] {
      while (!done || lidar.receive(std::chrono::milliseconds(0))) {
        if (auto d = lidar.receive(std::chrono::milliseconds(20))) lidar_datagrams.push_back(std::move(*d));
        while (auto d = imu.receive(std::chrono::milliseconds(0))) imu_datagrams.push_back(std::move(*d));
      }
    });
    PoseSender sender("127.0.0.1", pose_udp_port(daemon.log()));
    const Turn turn{kSimStart};
    const auto period = std::chrono::nanoseconds(static_cast<int64_t>(static_cast<double>(kStep) / speed));
    auto next = std::chrono::steady_clock::now();
    for (int i = 0; i < kPoses; ++i) {
      sender.send(pose_datagram(turn.at(kSimStart + i * kStep, static_cast<uint32_t>(i + 1))));
      next += period;
      std::this_thread::sleep_until(next);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the last burst arrives
    done = true;
    receiver.join();
  }
  // The sensor's time is the simulation's: the newest pose's, as the packets carry it.
  const json time = http.get_json("time/sensor").at("timestamp");
  EXPECT_DOUBLE_EQ(time.at("time").get<double>(), static_cast<double>(sim_end) * 1e-9) << time.dump();
  client.reset();  // closes the keep-alive connection, so the daemon stops at once
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();

  // Every packet whose last column is stamped up to sim_end, none later, each exactly once.
  const auto& f = metadata.format;
  const int64_t frame_ns = 1'000'000'000 / f.fps;
  const auto column_ns = [&](int m) { return static_cast<int64_t>(m) * 1'000'000'000 / (f.columns_per_frame * f.fps); };
  size_t expected = 0;
  for (int64_t frame = 0; kSimStart + frame * frame_ns <= sim_end; ++frame) {
    for (int p = 0; p < f.columns_per_frame / f.columns_per_packet; ++p) {
      expected += kSimStart + frame * frame_ns + column_ns((p + 1) * f.columns_per_packet - 1) <= sim_end;
    }
  }
  EXPECT_EQ(lidar_datagrams.size(), expected);
  ScanBatcher batcher(f);
  std::vector<BatchedFrame> frames;
  for (const Datagram& d : lidar_datagrams) {
    if (auto frame = batcher.add(d.bytes)) frames.push_back(std::move(*frame));
  }
  ASSERT_EQ(frames.size(), 8u);  // frames 0-7 complete; frame 8's first columns at sim_end came too
  expect_complete_scans(frames, metadata, 8);
  for (size_t k = 0; k < frames.size(); ++k) {
    const Scan& scan = frames[k].scan;
    for (int m = 0; m < scan.width; m += 97) {
      ASSERT_EQ(static_cast<int64_t>(scan.timestamp_ns[static_cast<size_t>(m)]),
                kSimStart + static_cast<int64_t>(k) * frame_ns + column_ns(m))
          << "frame " << k << " column " << m;
    }
  }
  // IMU samples every 10 ms of simulation from its start, on the same clock.
  ASSERT_EQ(imu_datagrams.size(), static_cast<size_t>(kPoses));
  for (size_t i = 0; i < imu_datagrams.size(); ++i) {
    uint64_t sys_ts = 0;
    std::memcpy(&sys_ts, imu_datagrams[i].bytes.data(), sizeof sys_ts);
    EXPECT_EQ(static_cast<int64_t>(sys_ts), kSimStart + static_cast<int64_t>(i) * kStep);
  }
}

INSTANTIATE_TEST_SUITE_P(Speeds, LockStep, ::testing::Values(0.3, 3.0), [](const auto& speed) {
  return speed.param < 1 ? "SlowerThanRealTime" : "FasterThanRealTime";
});

}  // namespace
}  // namespace lidartwin::e2e::live_poses_test
