#include "cli/serve_motion.h"

#include <numbers>

#include <fmt/format.h>

#include "lidartwin/error.h"

namespace lidartwin::cli {

namespace {

bool waits_for_client(const ServeFlags& flags) {
  if (flags.motion_start == "daemon") return false;
  if (flags.motion_start == "configured") return true;
  throw InputError("--motion-start " + flags.motion_start + ": must be daemon or configured");
}

}  // namespace

// Looping an open trajectory would jump the sensor from where it ends to where it starts
// (yard_flight.tum ends hovering 5 m above its pad): by default only one that closes loops.
TrajectoryEndChoice choose_trajectory_end(const std::string& flag, const Trajectory& trajectory) {
  const TrajectoryClosure gap = closure(trajectory);
  const std::string measured = fmt::format(
      "its last pose is {:.3f} m and {:.2f} deg from its first; it closes within {} m and {:.2f} deg", gap.gap_m,
      gap.gap_rad * 180.0 / std::numbers::pi, kClosesWithinM, kClosesWithinRad * 180.0 / std::numbers::pi);
  if (!flag.empty()) {
    const auto end = trajectory_end_from_string(flag);
    if (!end) throw InputError("--trajectory-end " + flag + ": must be hold, loop or stop");
    return {*end, "--trajectory-end " + flag + " (" + measured + ")"};
  }
  if (gap.closes()) return {TrajectoryEnd::kLoop, "it closes: " + measured};
  return {TrajectoryEnd::kHold, "it does not close: " + measured};
}

std::string_view meaning(TrajectoryEnd end) {
  switch (end) {
    case TrajectoryEnd::kHold: return "holds its last pose";
    case TrajectoryEnd::kLoop: return "loops";
    case TrajectoryEnd::kStop: return "stops the streams";
  }
  return "";
}

Motion load_motion(const ServeFlags& flags, int64_t epoch_steady_ns) {
  Motion motion;
  if (live(flags)) {
    if (!flags.pose.empty() || !flags.trajectory.empty()) {
      throw InputError("--live-poses/--pose-udp: the poses arrive live; leave out --pose and --trajectory");
    }
    if (!flags.trajectory_end.empty() || flags.motion_start != "daemon") {
      throw InputError("--trajectory-end/--motion-start: the poses arrive live; these play a trajectory");
    }
    // In lock-step the simulation's clock stands in for the host's (a zero epoch: pose time is
    // simulation time), and the streamer follows it.
    motion.live = std::make_unique<LivePoses>(live_pose_options(flags), flags.lock_step ? 0 : epoch_steady_ns);
    motion.description = flags.lock_step ? "live poses in lock-step with the simulation's clock" : "live poses";
    return motion;
  }
  const Trajectory trajectory = load_trajectory(flags);
  motion.waits_for_client = waits_for_client(flags);
  if (trajectory.samples().size() == 1) {
    if (flags.trajectory_end == "stop") {
      throw InputError("--trajectory-end stop: the sensor stands at one pose, which has no end to stop at");
    }
    motion.trajectory = std::make_unique<TrajectoryPlayback>(trajectory, TrajectoryEnd::kHold, false);
    motion.description = "a fixed pose";
    return motion;
  }
  const TrajectoryEndChoice end = choose_trajectory_end(flags.trajectory_end, trajectory);
  motion.trajectory = std::make_unique<TrajectoryPlayback>(trajectory, end.end, motion.waits_for_client);
  motion.description =
      fmt::format("trajectory of {:.2f} s, starting {}; at its end it {} ({})", trajectory.duration_s(),
                  motion.waits_for_client ? "when a client first configures the sensor (--motion-start configured)"
                                          : "with the daemon",
                  meaning(end.end), end.why);
  return motion;
}

}  // namespace lidartwin::cli
