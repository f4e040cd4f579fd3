#pragma once
// What moves the served sensor: live poses, or a trajectory (--pose, --trajectory, the default
// flight) played as --trajectory-end and --motion-start say.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "cli/serve_inputs.h"
#include "lidartwin/pose/live_poses.h"
#include "lidartwin/pose/trajectory_playback.h"

namespace lidartwin::cli {

struct Motion {
  std::unique_ptr<LivePoses> live;
  std::unique_ptr<TrajectoryPlayback> trajectory;
  bool waits_for_client = false;  // --motion-start configured
  std::string description;        // for the start-up log: what moves the sensor, and why so
  const PoseSource& poses() const { return live ? static_cast<const PoseSource&>(*live) : *trajectory; }
};

// Throws InputError naming the flag: live poses with --pose/--trajectory, a bad --trajectory-end or
// --motion-start, "stop" for a fixed pose.
Motion load_motion(const ServeFlags& flags, int64_t epoch_steady_ns);

// What a trajectory's end means (serve and record): --trajectory-end's value (`flag`), else loop a
// trajectory that closes and hold one that does not. `why` says which and how far it is from closing.
struct TrajectoryEndChoice {
  TrajectoryEnd end;
  std::string why;
};
TrajectoryEndChoice choose_trajectory_end(const std::string& flag, const Trajectory& trajectory);
std::string_view meaning(TrajectoryEnd end);  // "holds its last pose", "loops", "stops the streams"

}  // namespace lidartwin::cli
