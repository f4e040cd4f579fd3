// Acceptance: `lidartwin record --ideal` puts every point the SDK would compute from the capture on
// a surface of the scene (within 2 mm), and drops no return the scene offers within the profile's
// range window. Points are projected with the SDK formula (protocol doc 7.1) written in
// support/record_capture.h independently of the caster, with the recorded ground-truth pose.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "lidartwin/scene/scene.h"
#include "support/record_capture.h"
#include "support/surface_distance.h"

namespace lidartwin::cli_record_geometry_test {
namespace {

const std::filesystem::path kSource = LIDARTWIN_SOURCE_DIR;
const std::filesystem::path kHall = kSource / "scenes/calibration_hall.glb";
constexpr double kTolerance_m = 0.002;

using PoseAt = std::function<test::GroundTruthPose(double time_s)>;

struct Tally {
  size_t points = 0;
  size_t off_surface = 0;
  size_t dropped = 0;
  double worst_m = 0;
};

class RecordGeometry : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lidartwin_geometry_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // The sensor's clock reads kUptimeS at frame 0 (record --uptime-s); trajectories start at 0.
  static constexpr double kUptimeS = 12.5;

  std::filesystem::path record(const std::string& name, const std::string& arguments) {
    const auto out = dir_ / name;
    EXPECT_EQ(test::run_lidartwin("record --ideal --scene " + kHall.string() + " --frames 2 --seed 7 --uptime-s 12.5" +
                                  " --out " + out.string() + " " + arguments),
              0);
    return out;
  }

  // Checks every valid pixel of every frame; min/max range of the profile for the dropped test.
  Tally check(const std::filesystem::path& out, const PoseAt& pose_at, double min_range_m, double max_range_m) {
    const Scene scene = Scene::load(kHall);
    const auto beams = test::SdkIntrinsics::load(out / "metadata.json");
    const auto capture = test::decode_capture(out);
    EXPECT_EQ(capture.frames.size(), 2u);
    Tally tally;
    for (const auto& [frame_id, scan] : capture.frames) {
      for (int m = 0; m < scan.width; ++m) {
        EXPECT_NE(scan.status[static_cast<size_t>(m)], 0u) << "column " << m << " of frame " << frame_id;
        const auto pose = pose_at(static_cast<double>(scan.timestamp_ns[static_cast<size_t>(m)]) * 1e-9 - kUptimeS);
        for (int r = 0; r < scan.height; ++r) {
          check_pixel(scene, beams, pose, m, r, scan.at(ChannelField::kRange, m, r), min_range_m, max_range_m, tally);
        }
      }
    }
    return tally;
  }

  static void check_pixel(const Scene& scene, const test::SdkIntrinsics& beams, const test::GroundTruthPose& pose,
                          int m, int r, uint32_t range_mm, double min_range_m, double max_range_m, Tally& tally) {
    Eigen::Vector3d direction, origin;
    beams.lut(r, m, direction, origin);
    const Eigen::Vector3d world_origin = pose.rotation * origin + pose.translation;
    const Eigen::Vector3d world_direction = pose.rotation * direction;
    if (range_mm == 0) {
      // No return: the physical ray (from the beam origin) must meet nothing inside the window.
      const auto hit = scene.first_hit(world_origin, world_direction, static_cast<float>(beams.beam_offset_m()),
                                       static_cast<float>(max_range_m));
      const double distance = hit ? static_cast<double>(hit->distance) : std::numeric_limits<double>::infinity();
      if (distance > min_range_m + 0.01 && distance < max_range_m - 0.01) ++tally.dropped;
      return;
    }
    ++tally.points;
    const Eigen::Vector3d p = pose.rotation * beams.point(r, m, range_mm) + pose.translation;
    const double distance = test::distance_to_surface(scene.embree_scene(), p);
    tally.worst_m = std::max(tally.worst_m, std::isinf(distance) ? 1.0 : distance);
    if (distance > kTolerance_m) ++tally.off_surface;
  }

  std::filesystem::path dir_;
};

// The pose of the first row of poses.tum, for static recordings.
PoseAt static_pose(const std::filesystem::path& out) {
  const auto poses = test::read_poses(out / "poses.tum");
  EXPECT_EQ(poses.size(), 3u);  // each frame's start, and where the last one ends
  return [pose = poses.at(0)](double) { return pose; };
}

void expect_on_surfaces(const Tally& tally, size_t pixels) {
  EXPECT_GT(tally.points, pixels / 3) << "too few returns";
  EXPECT_EQ(tally.off_surface, 0u) << "worst distance " << tally.worst_m << " m";
  EXPECT_EQ(tally.dropped, 0u);
  std::printf("%zu points, worst distance to a surface %.3f mm, %zu dropped\n", tally.points, tally.worst_m * 1e3,
              tally.dropped);
}

const std::string kHallPose = "--trajectory " + (kSource / "scenes/calibration_hall_static.tum").string();

TEST_F(RecordGeometry, Os0PointsLieOnTheHall) {
  const auto out = record("os0", "--profile os0-64 --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16 " + kHallPose);
  expect_on_surfaces(check(out, static_pose(out), 0.3, 45.0), 2 * 1024 * 64);
}

// 5.1: LEGACY IMU at 100 Hz on the lidar's clock; at rest it reads +1 g along Z and no rotation.
TEST_F(RecordGeometry, ImuAtRestReadsGravity) {
  const auto out = record("imu", "--profile os1-64 --mode 1024x10 " + kHallPose);
  const auto capture = test::decode_capture(out);
  ASSERT_EQ(capture.imu.size(), 21u);  // t = 0, 0.01, ..., 0.20 s: two frames and their end
  for (size_t i = 0; i < capture.imu.size(); ++i) {
    const ImuSample& s = capture.imu[i];
    EXPECT_EQ(s.sys_ts_ns, 12'500'000'000u + i * 10'000'000u);
    EXPECT_NEAR(static_cast<double>(s.accel_g[2]), 1.0, 1e-6);
    for (const float v : {s.accel_g[0], s.accel_g[1], s.gyro_deg_s[0], s.gyro_deg_s[1], s.gyro_deg_s[2]}) {
      EXPECT_NEAR(static_cast<double>(v), 0.0, 1e-6);
    }
  }
}

// TIME_FROM_INTERNAL_OSC counts from power-on: by default a recording's first column is stamped
// 30 s (the sensor's boot and spin-up), its ground truth on the same clock, never 0 ns.
TEST_F(RecordGeometry, TimestampsCountFromASimulatedPowerOn) {
  const auto out = dir_ / "uptime";
  ASSERT_EQ(test::run_lidartwin("record --ideal --scene " + kHall.string() + " --frames 2 --profile os1-64 " +
                                "--mode 512x10 " + kHallPose + " --out " + out.string()),
            0);
  const auto capture = test::decode_capture(out);
  ASSERT_FALSE(capture.frames.empty());
  EXPECT_EQ(capture.frames.begin()->second.timestamp_ns[0], 30'000'000'000u);
  EXPECT_EQ(capture.imu.front().sys_ts_ns, 30'000'000'000u);
  EXPECT_DOUBLE_EQ(test::read_poses(out / "poses.tum").front().time_s, 30.0);
}

// The IMU sits at imu_to_sensor_transform (6.253, -11.775, 7.645) mm from the sensor's origin: spun
// at 360 deg/s about the sensor's z axis it reads the rate and, on its 13 mm lever arm, a
// centripetal force of omega^2 r (53 mg), exactly (an --ideal recording has an exact IMU).
TEST_F(RecordGeometry, ImuReadsTheKnownMotionAtItsOwnPosition) {
  const double omega = 2 * std::numbers::pi;  // rad/s
  const auto spin = dir_ / "spin.tum";
  {
    std::ofstream tum(spin);
    tum.precision(17);
    for (int k = 0; k <= 60; ++k) {  // 3 s, three whole turns: the looped trajectory stays smooth
      const double t = 0.05 * k;
      const Eigen::Quaterniond q(Eigen::AngleAxisd(omega * t, Eigen::Vector3d::UnitZ()));
      tum << t << " 0 0 4 " << q.x() << " " << q.y() << " " << q.z() << " " << q.w() << "\n";
    }
  }
  const auto out = record("spin", "--profile os1-64 --mode 1024x10 --trajectory " + spin.string());
  const auto capture = test::decode_capture(out);
  ASSERT_EQ(capture.imu.size(), 21u);
  const Eigen::Vector3d r(6.253e-3, -11.775e-3, 7.645e-3);  // the profile's imu_to_sensor_transform
  const double g = 9.80665;
  const Eigen::Vector3d expected_g(-omega * omega * r.x() / g, -omega * omega * r.y() / g, 1.0);
  for (const ImuSample& s : capture.imu) {
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(static_cast<double>(s.accel_g[static_cast<size_t>(i)]), expected_g[i], 1e-4) << "axis " << i;
    }
    EXPECT_NEAR(static_cast<double>(s.gyro_deg_s[2]), 360.0, 1e-3);
    EXPECT_NEAR(static_cast<double>(s.gyro_deg_s[0]), 0.0, 1e-4);
    EXPECT_NEAR(static_cast<double>(s.gyro_deg_s[1]), 0.0, 1e-4);
  }
}

// Without --ideal the datasheet profile's IMU errors are in the packets: at rest, white noise of
// density / sqrt(10 ms) on every axis (2.3 mg, 0.15 deg/s) and the gyro's g-sensitivity offset on
// the axis gravity acts along (0.1 deg/s/g); the same seed gives the same packets.
TEST_F(RecordGeometry, ImuNoiseFollowsTheProfile) {
  const auto noisy = [&](const std::string& name) {
    const auto out = dir_ / name;
    EXPECT_EQ(test::run_lidartwin("record --scene " + kHall.string() + " --frames 50 --seed 7 --profile os1-64 " +
                                  "--mode 512x10 " + kHallPose + " --out " + out.string()),
              0);
    return test::decode_capture(out).imu;
  };
  const auto imu = noisy("imu_noisy");
  ASSERT_EQ(imu.size(), 501u);
  const auto moments = [&](auto value) {
    double sum = 0, sum2 = 0;
    for (const ImuSample& s : imu) {
      const double v = value(s);
      sum += v;
      sum2 += v * v;
    }
    const double mean = sum / static_cast<double>(imu.size());
    return std::pair{mean, std::sqrt(sum2 / static_cast<double>(imu.size()) - mean * mean)};
  };
  const double accel_sigma_g = 2.2555e-3 / std::sqrt(0.01) / 9.80665;
  const double gyro_sigma_dps = 2.618e-4 / std::sqrt(0.01) * 180 / std::numbers::pi;
  for (size_t axis = 0; axis < 3; ++axis) {
    const auto [accel_mean, accel_sd] = moments([axis](const ImuSample& s) { return double{s.accel_g[axis]}; });
    const auto [gyro_mean, gyro_sd] = moments([axis](const ImuSample& s) { return double{s.gyro_deg_s[axis]}; });
    EXPECT_NEAR(accel_sd, accel_sigma_g, 0.15 * accel_sigma_g) << "axis " << axis;
    EXPECT_NEAR(gyro_sd, gyro_sigma_dps, 0.15 * gyro_sigma_dps) << "axis " << axis;
    EXPECT_NEAR(accel_mean, axis == 2 ? 1.0 : 0.0, 5 * accel_sigma_g / std::sqrt(501.0) + 1e-4) << "axis " << axis;
    const double g_sensitivity_dps = axis == 2 ? 1.78e-4 * 9.80665 * 180 / std::numbers::pi : 0.0;
    EXPECT_NEAR(gyro_mean, g_sensitivity_dps, 5 * gyro_sigma_dps / std::sqrt(501.0) + 0.01) << "axis " << axis;
  }
  EXPECT_EQ(noisy("imu_noisy_again"), imu);
}

TEST_F(RecordGeometry, Os1PointsLieOnTheHallInLegacyPackets) {
  const auto out = record("os1", "--profile os1-64 --mode 2048x10 --udp-profile LEGACY " + kHallPose);
  expect_on_surfaces(check(out, static_pose(out), 0.3, 100.0), 2 * 2048 * 64);
}

TEST_F(RecordGeometry, Os2PointsLieOnTheHallInDualPackets) {
  const auto out =
      record("os2", "--profile os2-64 --mode 512x20 --udp-profile RNG19_RFL8_SIG16_NIR16_DUAL " + kHallPose);
  expect_on_surfaces(check(out, static_pose(out), 0.8, 200.0), 2 * 512 * 64);
}

// E11: each column is cast from the pose at its own timestamp. The flight moves 10 m/s and yaws
// 90 deg/s, so using one pose per frame would put points up to 1 m off the walls.
TEST_F(RecordGeometry, MovingSensorUsesEachColumnsPose) {
  const double yaw_rate = std::numbers::pi / 2;  // rad/s
  const Eigen::Vector3d start(-5, 1, 4), velocity(10, 0, 0.5);
  const auto flight = dir_ / "flight.tum";
  {
    const Eigen::Quaterniond end_rotation(Eigen::AngleAxisd(yaw_rate * 2.0, Eigen::Vector3d::UnitZ()));
    const Eigen::Vector3d end = start + 2.0 * velocity;
    std::ofstream tum(flight);
    tum << "0 " << start.x() << " " << start.y() << " " << start.z() << " 0 0 0 1\n";
    tum.precision(17);
    tum << "2 " << end.x() << " " << end.y() << " " << end.z() << " " << end_rotation.x() << " " << end_rotation.y()
        << " " << end_rotation.z() << " " << end_rotation.w() << "\n";
  }
  const auto out = record("moving", "--profile os1-64 --mode 1024x10 --trajectory " + flight.string());
  // Independent of the pose module: constant velocity and yaw rate (what lerp + slerp give here).
  const PoseAt pose_at = [&](double t) {
    return test::GroundTruthPose{t, Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rate * t, Eigen::Vector3d::UnitZ())),
                                 start + t * velocity};
  };
  expect_on_surfaces(check(out, pose_at, 0.3, 100.0), 2 * 1024 * 64);
  // Ground truth at each frame's column 0, and where the last frame ends.
  const auto poses = test::read_poses(out / "poses.tum");
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_NEAR((poses[1].translation - pose_at(0.1).translation).norm(), 0.0, 1e-6);
  EXPECT_NEAR(poses[1].rotation.angularDistance(pose_at(0.1).rotation), 0.0, 1e-6);
  EXPECT_NEAR((poses[2].translation - pose_at(0.2).translation).norm(), 0.0, 1e-6);
  // Per column: the pose each column was cast from, at its timestamp (the packets' clock).
  const auto columns = test::read_poses(out / "column_poses.tum");
  ASSERT_EQ(columns.size(), 2u * 1024u);
  const auto capture = test::decode_capture(out);
  size_t checked = 0;
  for (const auto& [frame_id, scan] : capture.frames) {
    for (int m = 0; m < scan.width; m += 97) {
      const auto& truth =
          columns[static_cast<size_t>(frame_id - capture.frames.begin()->first) * 1024 + static_cast<size_t>(m)];
      EXPECT_NEAR(truth.time_s, static_cast<double>(scan.timestamp_ns[static_cast<size_t>(m)]) * 1e-9, 1e-9);
      EXPECT_NEAR((truth.translation - pose_at(truth.time_s - kUptimeS).translation).norm(), 0.0, 1e-6) << m;
      EXPECT_NEAR(truth.rotation.angularDistance(pose_at(truth.time_s - kUptimeS).rotation), 0.0, 1e-6) << m;
      ++checked;
    }
  }
  EXPECT_GT(checked, 10u);
}

}  // namespace
}  // namespace lidartwin::cli_record_geometry_test
