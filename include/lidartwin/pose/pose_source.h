#pragma once
// Where the sensor is at a given time: the one question the forward model asks of motion. A static
// pose and a TUM trajectory answer for any time; live sources (a HIL rig's pose stream, a vehicle
// with sensor mountings) answer only for the span they have heard about, and say so through span().
#include <cstdint>
#include <limits>
#include <memory>

#include "lidartwin/pose/pose.h"

namespace lidartwin {

// The times, in seconds on the source's clock, for which at() gives a pose it stands behind.
struct PoseSpan {
  double begin_s = -std::numeric_limits<double>::infinity();
  double end_s = std::numeric_limits<double>::infinity();
  bool contains(double time_s) const { return time_s >= begin_s && time_s <= end_s; }
  friend bool operator==(const PoseSpan&, const PoseSpan&) = default;
};

// How recent a live source's knowledge is: the number of poses it has accepted and when the newest
// arrived (host steady clock, ns). Sources that do not listen answer {0, 0}.
struct PoseFreshness {
  uint64_t revision = 0;
  int64_t arrival_steady_ns = 0;
};

// world_from_sensor over time. Implementations are read from several threads at once (the render
// workers cast columns in parallel), so at() and span() must be safe to call concurrently.
class PoseSource {
 public:
  virtual ~PoseSource() = default;
  // The pose at time_s; callers ask only for times inside span() (outside, the answer is the
  // source's best guess and the column is not observed: see ForwardModel).
  virtual Pose at(double time_s) const = 0;
  // What the source can answer for now. A live source's span grows as poses arrive ("not yet"
  // beyond its end) and may drop its beginning ("stale").
  virtual PoseSpan span() const = 0;
  // The time at which a recording from this source naturally starts (a trajectory's first pose).
  virtual double start_s() const = 0;
  // Live sources: what the poses at() answers from were last updated with (the streamer measures
  // from it the latency from a pose's arrival to the first packet cast with it).
  virtual PoseFreshness freshness() const { return {}; }
  // The same pose at every time (a fixed pose, a trajectory whose samples are all one): `record`
  // then writes no per-column poses (every column's pose is poses.tum's).
  virtual bool constant() const { return false; }
  // When the motion ends, on the source's clock: past it the sensor stops streaming (serve
  // --trajectory-end stop). +infinity: the motion never ends (it holds, loops or arrives live).
  virtual double end_s() const { return std::numeric_limits<double>::infinity(); }
};

// One pose forever.
class StaticPose final : public PoseSource {
 public:
  explicit StaticPose(const Pose& pose) : pose_(pose) {}
  Pose at(double) const override { return pose_; }
  PoseSpan span() const override { return {}; }
  double start_s() const override { return 0.0; }
  bool constant() const override { return true; }

 private:
  Pose pose_;
};

// A trajectory (TUM file): looping, or holding its end poses, it answers for any time.
class TrajectoryPoses final : public PoseSource {
 public:
  explicit TrajectoryPoses(Trajectory trajectory) : trajectory_(std::move(trajectory)) {}
  // Answering only for span: the analysis does not stand behind poses a measured trajectory does
  // not cover (held end poses would compare the sensor at the wrong place).
  TrajectoryPoses(Trajectory trajectory, PoseSpan span) : trajectory_(std::move(trajectory)), span_(span) {}
  Pose at(double time_s) const override { return trajectory_.at(time_s); }
  PoseSpan span() const override { return span_; }
  double start_s() const override { return trajectory_.start_s(); }
  bool constant() const override;
  const Trajectory& trajectory() const { return trajectory_; }

 private:
  Trajectory trajectory_;
  PoseSpan span_;
};

// A sensor mounted on a vehicle: the vehicle's motion (world_from_vehicle) composed with the
// mounting (vehicle_from_sensor), so several sensors of a rig follow one pose stream.
class MountedPoses final : public PoseSource {
 public:
  MountedPoses(const PoseSource& vehicle, const Pose& vehicle_from_sensor)
      : vehicle_(vehicle), mounting_(vehicle_from_sensor) {}
  Pose at(double time_s) const override { return vehicle_.at(time_s) * mounting_; }
  PoseSpan span() const override { return vehicle_.span(); }
  double start_s() const override { return vehicle_.start_s(); }
  PoseFreshness freshness() const override { return vehicle_.freshness(); }
  bool constant() const override { return vehicle_.constant(); }
  double end_s() const override { return vehicle_.end_s(); }

 private:
  const PoseSource& vehicle_;
  Pose mounting_;
};

// The pose sources that hold a Pose share its one layout (pose.h).
static_assert(alignof(StaticPose) == 16 && sizeof(StaticPose) == 80);
static_assert(alignof(MountedPoses) == 16 && sizeof(MountedPoses) == 80);

}  // namespace lidartwin
