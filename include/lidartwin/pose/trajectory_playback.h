#pragma once
// A trajectory as `serve` plays it on the rig's clock: when its motion starts (with the daemon, or
// when a client first configures the sensor) and what its end means (hold the last pose, loop,
// or stop streaming).
#include <atomic>
#include <optional>
#include <string_view>

#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_source.h"

namespace lidartwin {

enum class TrajectoryEnd { kHold, kLoop, kStop };
std::string_view to_string(TrajectoryEnd end);  // "hold", "loop", "stop"
std::optional<TrajectoryEnd> trajectory_end_from_string(std::string_view text);

// A trajectory closes when its last pose is its first to within these: below an OS sensor's range
// noise (1-3 cm, 1 sigma) and the angle that moves a point 10 m away by 1 cm, so looping it makes
// no jump a lidar could see.
inline constexpr double kClosesWithinM = 0.01;
inline constexpr double kClosesWithinRad = 0.001;

struct TrajectoryClosure {
  double gap_m = 0.0;    // from the last position to the first
  double gap_rad = 0.0;  // rotation angle from the last orientation to the first
  bool closes() const { return gap_m <= kClosesWithinM && gap_rad <= kClosesWithinRad; }
};
TrajectoryClosure closure(const Trajectory& trajectory);

// Thread-safe: at() runs on the render workers while start_at() runs on a client's HTTP thread.
class TrajectoryPlayback final : public PoseSource {
 public:
  // The trajectory's first time plays at rig time trajectory.start_s(), or, when `deferred`, at
  // the rig time start_at() names; until then the sensor holds the first pose.
  TrajectoryPlayback(const Trajectory& trajectory, TrajectoryEnd end, bool deferred);

  Pose at(double time_s) const override;
  PoseSpan span() const override { return {}; }
  double start_s() const override { return trajectory_.start_s(); }
  bool constant() const override { return poses_.constant(); }
  double end_s() const override;  // kStop: where the last pose plays; otherwise never

  // Deferred playback: the motion starts at rig time time_s. The first call wins; returns whether
  // this one started it.
  bool start_at(double time_s);
  std::optional<double> started_at() const;  // rig time of the trajectory's first pose, once known

 private:
  Trajectory trajectory_;  // loops with kLoop, else holds its last pose
  TrajectoryPoses poses_;
  TrajectoryEnd end_;
  std::atomic<double> started_at_;  // +infinity until started
};

}  // namespace lidartwin
