#pragma once
// Where a moving sensor was, from its own capture (`compare --map` without --pose): the frames are
// registered to each other, point to plane. The trajectory is a pose at each frame's first column
// and one where the last frame ends, linearly interpolated between them (as TUM trajectories are),
// so every column is placed by the pose at its own time: the motion within a frame (a quarter of a
// metre at 2.5 m/s and 10 Hz) is estimated with the rest, not ignored. All knots are solved
// together (Gauss-Newton): each point of frame k is associated with the nearest point of frames
// k - 1 and k + 1 through their own beam grids, its residual is the distance to that point's local
// plane, and the residual moves the knots on both sides of both points' columns. The first knot is
// the world frame.
#include <cstddef>

#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/pose/pose.h"

namespace lidartwin {

struct RegistrationOptions {
  size_t points_per_frame = 6000;  // source points sampled evenly from each frame's returns
  int max_iterations = 30;
  double min_range_m = 1.0;  // nearer returns are left out (the vehicle, the operator)
  double max_range_m = 100.0;
};

struct FrameRegistration {
  Trajectory trajectory{std::vector<StampedPose>{StampedPose{}}, false};  // world_from_sensor, capture clock
  size_t pairs = 0;                                                       // point-to-plane pairs in the last iteration
  double rms_m = 0.0;                                                     // their robust RMS distance to the planes
  int iterations = 0;
  double path_length_m = 0.0;  // how far the sensor travelled
};

// Throws InputError when the capture has fewer than two frames or too few returns to register.
FrameRegistration register_frames(const MeasuredCapture& capture, WorkerPool& pool,
                                  const RegistrationOptions& options = {});

}  // namespace lidartwin
