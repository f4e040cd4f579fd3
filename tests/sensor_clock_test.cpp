// The sensor's clock without sockets: which packets a window sends, when they are due, which
// frame_id they carry, and what the IMU reads. Expected values come from the protocol doc (6.1,
// 6.4: real windowed captures) and closed forms, not from the code's own output.
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/frame/imu_model.h"
#include "lidartwin/frame/packet_plan.h"
#include "lidartwin/frame/sensor_clock.h"

namespace lidartwin {
namespace {

LidarDataFormat format_of(int width, int fps, std::array<int, 2> window, int columns_per_packet = 16) {
  LidarDataFormat format;
  format.columns_per_frame = width;
  format.fps = fps;
  format.column_window = window;
  format.columns_per_packet = columns_per_packet;
  return format;
}

TEST(PacketSchedule, FullWindowSendsEveryPacket) {
  const auto firsts = packets_to_send(format_of(1024, 10, {0, 1023}));
  ASSERT_EQ(firsts.size(), 64u);
  for (size_t i = 0; i < firsts.size(); ++i) EXPECT_EQ(firsts[i], static_cast<int>(i) * 16);
}

// windowed_frame1.pcap: azimuth [180000, 360000] -> column_window [1, 256] at 512, 17 packets (6.4).
TEST(PacketSchedule, WindowSendsOnlyPacketsMeetingIt) {
  const auto firsts = packets_to_send(format_of(512, 10, {1, 256}));
  ASSERT_EQ(firsts.size(), 17u);
  EXPECT_EQ(firsts.front(), 0);
  EXPECT_EQ(firsts.back(), 256);
}

// windowed_frame2.pcap: [370, 85] wraps through 0: m 0-95 and 368-511 in one frame, 15 packets.
TEST(PacketSchedule, WrappingWindowStartsTheFrameAtZero) {
  const auto firsts = packets_to_send(format_of(512, 10, {370, 85}));
  const std::vector<int> expected{0, 16, 32, 48, 64, 80, 368, 384, 400, 416, 432, 448, 464, 480, 496};
  EXPECT_EQ(firsts, expected);
}

TEST(PacketSchedule, WrappingWindowWithBothEndsInOnePacketSendsAll) {
  EXPECT_EQ(packets_to_send(format_of(512, 10, {10, 5})).size(), 32u);
  EXPECT_EQ(packets_to_send(format_of(512, 10, {5, 10})).size(), 1u);
}

TEST(PacketSchedule, ColumnsPerPacketDividesTheFrame) {
  EXPECT_EQ(packets_to_send(format_of(2048, 10, {0, 2047}, 8)).size(), 256u);
  EXPECT_EQ(packets_to_send(format_of(512, 20, {0, 511}, 64)).size(), 8u);
  EXPECT_EQ(packets_to_send(format_of(1024, 10, {0, 1023}, 1)).size(), 1024u);
}

SensorClock clock_of(int width, int fps, uint64_t origin_ns = 0, double pose_origin_s = 0.0) {
  SensorClock clock;
  clock.columns_per_frame = width;
  clock.fps = fps;
  clock.origin_ns = origin_ns;
  clock.pose_origin_s = pose_origin_s;
  return clock;
}

TEST(SensorClock, FramesAndColumnsFollowTheMode) {
  const SensorClock clock = clock_of(1024, 10);
  EXPECT_EQ(clock.frame_period_ns(), 100'000'000u);
  EXPECT_EQ(clock.column_offset_ns(1), 97'656u);  // 97 656.25 ns, rounded down (6.1)
  EXPECT_EQ(clock.column_offset_ns(1024), 100'000'000u);
  EXPECT_EQ(clock.column_timestamp_ns(3, 1024), clock.column_timestamp_ns(4, 0));
  EXPECT_EQ(clock_of(512, 10).column_offset_ns(2), 390'625u);
  EXPECT_EQ(clock_of(2048, 10).column_offset_ns(1), 48'828u);
}

// 6.1, 6.3: column m of frame k is stamped origin + k / fps + floor(m * 1e9 / (W * fps)).
TEST(SensorClock, TimestampsCountFromTheOrigin) {
  const SensorClock clock = clock_of(512, 10, 1'000'000'000);
  EXPECT_EQ(clock.column_timestamp_ns(0, 0), 1'000'000'000u);
  EXPECT_EQ(clock.column_timestamp_ns(3, 7), 1'300'000'000u + 7 * 1'000'000'000ull / 5120);
  // A packet leaves when its last column is observed.
  EXPECT_EQ(clock.packet_timestamp_ns(3, 16, 16), clock.column_timestamp_ns(3, 31));
}

TEST(SensorClock, PoseTimesFollowTheColumnsFromThePoseOrigin) {
  const SensorClock clock = clock_of(1024, 20, 0, 12.5);
  EXPECT_DOUBLE_EQ(clock.column_pose_time_s(0, 0), 12.5);
  EXPECT_DOUBLE_EQ(clock.column_pose_time_s(2, 512), 12.5 + 0.1 + 0.025);
  EXPECT_DOUBLE_EQ(clock.imu_pose_time_s(3), 12.53);
}

// 5.1: IMU samples every 10 ms from the origin, on the lidar's clock.
TEST(SensorClock, ImuSamplesShareTheLidarClock) {
  const SensorClock clock = clock_of(1024, 20, 500);
  EXPECT_EQ(clock.imu_timestamp_ns(0), 500u);
  EXPECT_EQ(clock.imu_timestamp_ns(4), 500u + 40'000'000u);
}

// Deadlines of consecutive packets, across several frames, are cpp column periods apart to within
// the 1 ns rounding, so a frame is spread evenly over its period (protocol doc 1 item 12).
TEST(PacketSchedule, DeadlinesAreEvenlySpacedAcrossFrames) {
  for (const auto& [width, fps] : std::vector<std::pair<int, int>>{{512, 10}, {1024, 10}, {1024, 20}, {2048, 10}}) {
    const auto format = format_of(width, fps, {0, width - 1});
    const SensorClock clock = clock_of(width, fps);
    const double spacing_ns = 16.0 * 1e9 / (width * fps);
    std::vector<uint64_t> deadlines;
    for (uint64_t frame = 0; frame < 3; ++frame) {
      for (const int first : packets_to_send(format)) {
        deadlines.push_back(clock.packet_timestamp_ns(frame, first, 16));
      }
    }
    for (size_t i = 1; i < deadlines.size(); ++i) {
      const double step = static_cast<double>(deadlines[i] - deadlines[i - 1]);
      EXPECT_NEAR(step, spacing_ns, 1.0) << width << "x" << fps << " packet " << i;
    }
    // The last packet of a frame is due when its last column, W-1, is observed.
    EXPECT_EQ(clock.packet_due_offset_ns(width - 16, 16), clock.column_offset_ns(width - 1));
  }
}

TEST(FrameId, WrapsAtSixteenBitsOrThirtyTwoForFusa) {
  const auto standard = format_of(1024, 10, {0, 1023});
  EXPECT_EQ(frame_id_of(0, standard), 0u);
  EXPECT_EQ(frame_id_of(1, standard), 1u);
  EXPECT_EQ(frame_id_of(65535, standard), 65535u);
  EXPECT_EQ(frame_id_of(65536, standard), 0u);
  EXPECT_EQ(frame_id_of(65537, standard), 1u);

  auto fusa = standard;
  fusa.header_type = HeaderType::kFusa;
  EXPECT_TRUE(uses_fusa_header(fusa));
  EXPECT_EQ(frame_id_of(65536, fusa), 65536u);
  EXPECT_EQ(frame_id_of(uint64_t{1} << 32, fusa), 0u);
  auto fusa_profile = standard;
  fusa_profile.udp_profile_lidar = UdpProfileLidar::kFusaRng15Rfl8Nir8Dual;
  EXPECT_EQ(frame_id_of(70000, fusa_profile), 70000u);
}

Pose pose_of(Eigen::Vector3d translation, Eigen::Quaterniond rotation) {
  Pose pose;
  pose.translation = translation;
  pose.rotation = rotation;
  return pose;
}

TEST(ImuModel, AtRestReadsOneGUp) {
  const auto sample = imu_sample(StaticPose(Pose{}), 1.0, 5'000'000'000);
  EXPECT_NEAR(sample.accel_g[0], 0.0f, 1e-6f);
  EXPECT_NEAR(sample.accel_g[1], 0.0f, 1e-6f);
  EXPECT_NEAR(sample.accel_g[2], 1.0f, 1e-6f);
  for (const float w : sample.gyro_deg_s) EXPECT_NEAR(w, 0.0f, 1e-6f);
  EXPECT_EQ(sample.sys_ts_ns, 5'000'000'000u);
  EXPECT_LT(sample.accel_ts_ns, sample.sys_ts_ns);
  EXPECT_NE(sample.gyro_ts_ns, 0u);
}

// Rolled 90 degrees about +X: the sensor's +Y points up, so gravity's reaction reads +1 g on Y.
TEST(ImuModel, GravityIsExpressedInTheSensorFrame) {
  const Eigen::Quaterniond roll(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()));
  const auto sample = imu_sample(StaticPose(pose_of(Eigen::Vector3d(1, 2, 3), roll)), 0.0, 1);
  EXPECT_NEAR(sample.accel_g[0], 0.0f, 1e-6f);
  EXPECT_NEAR(sample.accel_g[1], 1.0f, 1e-6f);
  EXPECT_NEAR(sample.accel_g[2], 0.0f, 1e-6f);
}

// Yawing at 0.5 rad/s while moving at constant velocity: gyro z = 28.65 deg/s, no extra force.
TEST(ImuModel, ReadsTheTrajectorysRotationRate) {
  std::vector<StampedPose> samples;
  for (int i = 0; i <= 100; ++i) {
    const double t = 0.1 * i;
    const Eigen::Quaterniond yaw(Eigen::AngleAxisd(0.5 * t, Eigen::Vector3d::UnitZ()));
    samples.push_back({t, pose_of(Eigen::Vector3d(2.0 * t, 0, 0), yaw)});
  }
  const TrajectoryPoses trajectory(Trajectory(samples, false));
  const auto sample = imu_sample(trajectory, 5.0, 1);
  EXPECT_NEAR(sample.gyro_deg_s[2], 0.5 * 180.0 / std::numbers::pi, 1e-3);
  EXPECT_NEAR(sample.gyro_deg_s[0], 0.0f, 1e-4f);
  EXPECT_NEAR(sample.accel_g[2], 1.0f, 1e-5f);
  EXPECT_NEAR(std::hypot(sample.accel_g[0], sample.accel_g[1]), 0.0, 1e-5);
}

// Bias random walk alone: consecutive samples differ by walk * sqrt(period) * N(0, 1), so their
// differences have that spread and the bias wanders; asking out of order gives the same values.
TEST(ImuErrors, BiasesWalkAndEverySampleIsAPureFunctionOfSeedAndIndex) {
  ImuNoise noise;
  noise.accelerometer_random_walk = 0.01;
  noise.gyroscope_random_walk = 0.001;
  const ImuErrors errors(noise, 42, 0.01);
  const ImuReading exact;
  std::vector<ImuReading> readings;
  for (uint64_t i = 0; i < 4000; ++i) readings.push_back(errors.apply(i, exact));
  double sum2_accel = 0, sum2_gyro = 0;
  for (size_t i = 1; i < readings.size(); ++i) {
    sum2_accel += (readings[i].specific_force - readings[i - 1].specific_force).squaredNorm();
    sum2_gyro += (readings[i].angular_rate - readings[i - 1].angular_rate).squaredNorm();
  }
  const double n = 3.0 * static_cast<double>(readings.size() - 1);
  EXPECT_NEAR(std::sqrt(sum2_accel / n), 0.01 * 0.1, 0.05 * 0.001);
  EXPECT_NEAR(std::sqrt(sum2_gyro / n), 0.001 * 0.1, 0.05 * 0.0001);
  EXPECT_EQ(readings[0].specific_force, Eigen::Vector3d::Zero());  // the walk starts at zero
  const ImuErrors again(noise, 42, 0.01);
  EXPECT_EQ(again.apply(3000, exact).specific_force, readings[3000].specific_force);
  EXPECT_EQ(again.apply(17, exact).angular_rate, readings[17].angular_rate);  // backwards
  EXPECT_NE(ImuErrors(noise, 43, 0.01).apply(17, exact).angular_rate, readings[17].angular_rate);
}

}  // namespace
}  // namespace lidartwin
