// TrajectoryPlayback: when a closed trajectory closes (the stated tolerance, on position and on
// rotation), what its end means (hold, loop, stop), and a motion that waits for its start.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "lidartwin/pose/trajectory_playback.h"

namespace lidartwin {
namespace {

StampedPose at(double time_s, double x, double yaw_rad = 0.0) {
  StampedPose s;
  s.time_s = time_s;
  s.pose.translation = {x, 0.0, 1.0};
  s.pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  return s;
}

// x from 0 to 2 over 10..12 s: open.
Trajectory open_flight() { return Trajectory({at(10.0, 0.0), at(11.0, 1.0), at(12.0, 2.0)}); }

TEST(TrajectoryClosure, ClosesWithinOneCentimetreAndOneMilliradian) {
  EXPECT_TRUE(closure(Trajectory({at(0, 0.0), at(1, 5.0), at(2, 0.0)})).closes());
  EXPECT_TRUE(closure(Trajectory({at(0, 0.0), at(1, 5.0), at(2, 0.0099, 0.00099)})).closes());
  EXPECT_FALSE(closure(Trajectory({at(0, 0.0), at(1, 5.0), at(2, 0.0101)})).closes());
  EXPECT_FALSE(closure(Trajectory({at(0, 0.0), at(1, 5.0), at(2, 0.0, 0.0011)})).closes());
  const TrajectoryClosure gap = closure(open_flight());
  EXPECT_DOUBLE_EQ(gap.gap_m, 2.0);
  EXPECT_FALSE(gap.closes());
}

TEST(TrajectoryPlayback, HoldsLoopsOrStopsAtTheEnd) {
  const TrajectoryPlayback hold(open_flight(), TrajectoryEnd::kHold, false);
  const TrajectoryPlayback loop(open_flight(), TrajectoryEnd::kLoop, false);
  const TrajectoryPlayback stop(open_flight(), TrajectoryEnd::kStop, false);
  EXPECT_DOUBLE_EQ(hold.at(10.5).translation.x(), 0.5);  // the trajectory's own times, as before
  EXPECT_DOUBLE_EQ(hold.at(13.5).translation.x(), 2.0);
  EXPECT_DOUBLE_EQ(loop.at(13.5).translation.x(), 1.5);
  EXPECT_EQ(hold.end_s(), std::numeric_limits<double>::infinity());
  EXPECT_EQ(loop.end_s(), std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(stop.end_s(), 12.0);
}

TEST(TrajectoryPlayback, AWaitingMotionHoldsTheFirstPoseUntilItStarts) {
  TrajectoryPlayback waiting(open_flight(), TrajectoryEnd::kStop, true);
  EXPECT_FALSE(waiting.started_at());
  EXPECT_DOUBLE_EQ(waiting.at(11.5).translation.x(), 0.0);
  EXPECT_EQ(waiting.end_s(), std::numeric_limits<double>::infinity());  // no end before a start
  EXPECT_TRUE(waiting.start_at(100.0));
  EXPECT_FALSE(waiting.start_at(50.0));  // the first start wins
  EXPECT_DOUBLE_EQ(*waiting.started_at(), 100.0);
  EXPECT_DOUBLE_EQ(waiting.at(99.0).translation.x(), 0.0);
  EXPECT_DOUBLE_EQ(waiting.at(101.5).translation.x(), 1.5);
  EXPECT_DOUBLE_EQ(waiting.end_s(), 102.0);
}

TEST(TrajectoryEnd, NamesReadBack) {
  for (const TrajectoryEnd end : {TrajectoryEnd::kHold, TrajectoryEnd::kLoop, TrajectoryEnd::kStop}) {
    EXPECT_EQ(trajectory_end_from_string(to_string(end)), end);
  }
  EXPECT_FALSE(trajectory_end_from_string("Hold"));
}

}  // namespace
}  // namespace lidartwin
