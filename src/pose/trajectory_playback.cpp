#include "lidartwin/pose/trajectory_playback.h"

#include <cmath>
#include <limits>

namespace lidartwin {

namespace {
constexpr double kNotStarted = std::numeric_limits<double>::infinity();

Trajectory played(const Trajectory& trajectory, TrajectoryEnd end) {
  return Trajectory(trajectory.samples(), end == TrajectoryEnd::kLoop);
}
}  // namespace

std::string_view to_string(TrajectoryEnd end) {
  switch (end) {
    case TrajectoryEnd::kHold: return "hold";
    case TrajectoryEnd::kLoop: return "loop";
    case TrajectoryEnd::kStop: return "stop";
  }
  return "hold";
}

std::optional<TrajectoryEnd> trajectory_end_from_string(std::string_view text) {
  if (text == "hold") return TrajectoryEnd::kHold;
  if (text == "loop") return TrajectoryEnd::kLoop;
  if (text == "stop") return TrajectoryEnd::kStop;
  return std::nullopt;
}

TrajectoryClosure closure(const Trajectory& trajectory) {
  const Pose& first = trajectory.samples().front().pose;
  const Pose& last = trajectory.samples().back().pose;
  return {(last.translation - first.translation).norm(), first.rotation.angularDistance(last.rotation)};
}

TrajectoryPlayback::TrajectoryPlayback(const Trajectory& trajectory, TrajectoryEnd end, bool deferred)
    : trajectory_(played(trajectory, end)),
      poses_(trajectory_),
      end_(end),
      started_at_(deferred ? kNotStarted : trajectory.start_s()) {}

Pose TrajectoryPlayback::at(double time_s) const {
  const double started = started_at_.load(std::memory_order_acquire);
  if (!(time_s >= started)) return trajectory_.samples().front().pose;  // also before a deferred start
  return trajectory_.at(trajectory_.start_s() + (time_s - started));
}

double TrajectoryPlayback::end_s() const {
  if (end_ != TrajectoryEnd::kStop) return kNotStarted;
  return started_at_.load(std::memory_order_acquire) + trajectory_.duration_s();
}

bool TrajectoryPlayback::start_at(double time_s) {
  double expected = kNotStarted;
  return started_at_.compare_exchange_strong(expected, time_s, std::memory_order_acq_rel);
}

std::optional<double> TrajectoryPlayback::started_at() const {
  const double started = started_at_.load(std::memory_order_acquire);
  if (std::isinf(started)) return std::nullopt;
  return started;
}

}  // namespace lidartwin
