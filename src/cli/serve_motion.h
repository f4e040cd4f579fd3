#pragma once
// What moves the served sensor: live poses, or a trajectory (--pose, --trajectory, the default
// flight) played as --trajectory-end and --motion-start say.
#include <cstdint>
#include <memory>
#include <string>

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

}  // namespace lidartwin::cli
