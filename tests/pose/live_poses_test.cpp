// LivePoses: interpolation between received poses, bounded extrapolation past the newest, the span
// it stands behind, the clocks, and the counting of refused and lost messages.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "lidartwin/pose/live_poses.h"

namespace lidartwin {
namespace {

constexpr int64_t kEpoch = 1'000'000'000'000;  // the rig's time zero on the steady clock
constexpr int64_t kMs = 1'000'000;

PoseMessage at_x(uint32_t sequence, int64_t time_ns, double x, double yaw_rad = 0.0) {
  PoseMessage m;
  m.sequence = sequence;
  m.time_ns = time_ns;
  m.pose.translation = {x, 0.0, 1.0};
  m.pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  return m;
}

double yaw_of(const Pose& pose) {
  const Eigen::Vector3d x = pose.rotation * Eigen::Vector3d::UnitX();
  return std::atan2(x.y(), x.x());
}

LivePoses monotonic(PoseTimeout timeout = PoseTimeout::kInvalid, double extrapolation_s = 0.1) {
  LivePoseOptions options;
  options.clock = PoseClock::kMonotonic;
  options.timeout = timeout;
  options.max_extrapolation_s = extrapolation_s;
  return LivePoses(options, kEpoch);
}

TEST(LivePoses, AnswersForNothingBeforeTheFirstPose) {
  const LivePoses poses = monotonic();
  EXPECT_FALSE(poses.span().contains(0.0));
  EXPECT_FALSE(poses.span().contains(1e9));
  EXPECT_EQ(poses.freshness().revision, 0u);
}

TEST(LivePoses, InterpolatesBetweenPosesOnTheSteadyClock) {
  LivePoses poses = monotonic();
  // Monotonic clock: a pose stamped kEpoch + 100 ms is at source time 0.1 s.
  poses.receive(at_x(1, kEpoch + 100 * kMs, 0.0, 0.0), kEpoch + 100 * kMs);
  poses.receive(at_x(2, kEpoch + 200 * kMs, 1.0, std::numbers::pi / 2), kEpoch + 200 * kMs);
  const Pose mid = poses.at(0.125);
  EXPECT_NEAR(mid.translation.x(), 0.25, 1e-9);
  EXPECT_NEAR(yaw_of(mid), std::numbers::pi / 8, 1e-9);
  EXPECT_NEAR(poses.at(0.1).translation.x(), 0.0, 1e-12);
  EXPECT_NEAR(poses.at(0.2).translation.x(), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(poses.span().begin_s, 0.1);
  EXPECT_NEAR(poses.span().end_s, 0.3, 1e-12);  // the newest plus 100 ms of extrapolation
  EXPECT_EQ(poses.freshness().revision, 2u);
  EXPECT_EQ(poses.freshness().arrival_steady_ns, kEpoch + 200 * kMs);
}

TEST(LivePoses, ExtrapolatesFromTheDifferenceOfTheNewestTwoUpToTheBound) {
  LivePoses poses = monotonic(PoseTimeout::kHold, 0.05);
  poses.receive(at_x(1, kEpoch, 0.0, 0.0), kEpoch);
  poses.receive(at_x(2, kEpoch + 10 * kMs, 0.1, 0.01), kEpoch + 10 * kMs);  // 10 m/s, 1 rad/s
  EXPECT_NEAR(poses.at(0.03).translation.x(), 0.3, 1e-9);
  EXPECT_NEAR(yaw_of(poses.at(0.03)), 0.03, 1e-9);
  // Held where the 50 ms of extrapolation ended; with kHold the span has no end.
  EXPECT_NEAR(poses.at(5.0).translation.x(), 0.6, 1e-9);
  EXPECT_TRUE(poses.span().contains(1e6));
}

TEST(LivePoses, ExtrapolatesWithTheMessagesOwnVelocityAndRate) {
  LivePoses poses = monotonic();
  PoseMessage m = at_x(1, kEpoch, 2.0);
  m.velocity = Eigen::Vector3d(0.0, 4.0, 0.0);
  m.angular_rate = Eigen::Vector3d(0.0, 0.0, std::numbers::pi / 2);  // 90 deg/s
  poses.receive(m, kEpoch);
  const Pose ahead = poses.at(0.02);
  EXPECT_NEAR(ahead.translation.y(), 0.08, 1e-12);
  EXPECT_NEAR(yaw_of(ahead), std::numbers::pi / 2 * 0.02, 1e-12);
}

TEST(LivePoses, InvalidAndStandbyEndTheSpanAtTheBound) {
  for (PoseTimeout timeout : {PoseTimeout::kInvalid, PoseTimeout::kStandby}) {
    LivePoses poses = monotonic(timeout, 0.05);
    poses.receive(at_x(1, kEpoch + 1000 * kMs, 0.0), kEpoch + 1000 * kMs);
    EXPECT_TRUE(poses.span().contains(1.05));
    EXPECT_FALSE(poses.span().contains(1.051));
    EXPECT_FALSE(poses.span().contains(0.999));
  }
}

TEST(LivePoses, RefusesTimeGoingBackwardsAndCountsLostSequences) {
  LivePoses poses = monotonic();
  poses.receive(at_x(1, kEpoch + 10 * kMs, 0.0), kEpoch);
  EXPECT_THROW(poses.receive(at_x(2, kEpoch + 10 * kMs, 5.0), kEpoch), PoseRejected);  // repeated time
  EXPECT_THROW(poses.receive(at_x(3, kEpoch + 5 * kMs, 5.0), kEpoch), PoseRejected);   // older
  poses.receive(at_x(7, kEpoch + 20 * kMs, 1.0), kEpoch);                              // 2..6 lost
  const LivePoseStats stats = poses.stats();
  EXPECT_EQ(stats.accepted, 2u);
  EXPECT_EQ(stats.rejected[static_cast<size_t>(PoseRejection::kTimeBackwards)], 2u);
  EXPECT_EQ(stats.lost, 5u);
  EXPECT_NEAR(poses.at(0.015).translation.x(), 0.5, 1e-9);  // the refused poses left no trace
}

TEST(LivePoses, SenderClockIsMappedByTheFastestTransit) {
  LivePoseOptions options;
  options.clock = PoseClock::kSender;
  LivePoses poses(options, kEpoch);
  // The sender's clock reads 5 s when the host's reads kEpoch + 1 s; transits of 3 ms then 1 ms.
  const int64_t sender_at_host_1s = 5'000'000'000;
  poses.receive(at_x(1, sender_at_host_1s, 0.0), kEpoch + 1000 * kMs + 3 * kMs);
  EXPECT_EQ(poses.stats().clock_offset_ns, kEpoch + 1000 * kMs + 3 * kMs - sender_at_host_1s);
  poses.receive(at_x(2, sender_at_host_1s + 100 * kMs, 1.0), kEpoch + 1100 * kMs + 1 * kMs);
  EXPECT_EQ(poses.stats().clock_offset_ns, kEpoch + 1000 * kMs + 1 * kMs - sender_at_host_1s);
  EXPECT_NEAR(poses.span().begin_s, 1.001, 1e-9);
  EXPECT_NEAR(poses.at(1.051).translation.x(), 0.5, 1e-9);
}

TEST(LivePoses, ForgetsPosesOlderThanTheHistory) {
  LivePoseOptions options;
  options.clock = PoseClock::kMonotonic;
  options.history_s = 1.0;
  LivePoses poses(options, kEpoch);
  for (uint32_t i = 0; i <= 30; ++i) poses.receive(at_x(i, kEpoch + i * 100 * kMs, i), kEpoch + i * 100 * kMs);
  EXPECT_NEAR(poses.span().begin_s, 2.0, 1e-9);
}

TEST(MountedPoses, ComposesTheVehicleMotionWithTheMounting) {
  LivePoses poses = monotonic();
  poses.receive(at_x(1, kEpoch, 10.0, std::numbers::pi / 2), kEpoch);
  Pose mounting;
  mounting.translation = {1.0, 0.0, 0.5};  // 1 m ahead of the vehicle's origin, 0.5 m up
  const MountedPoses sensor(poses, mounting);
  const Pose p = sensor.at(0.0);
  EXPECT_NEAR((p.translation - Eigen::Vector3d(10.0, 1.0, 1.5)).norm(), 0.0, 1e-12);  // ahead is +y
  EXPECT_EQ(sensor.span(), poses.span());
}

}  // namespace
}  // namespace lidartwin
