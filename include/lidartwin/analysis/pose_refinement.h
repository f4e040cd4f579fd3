#pragma once
// Measured poses are never exact (`compare --refine-pose`): register the capture's measured points
// to the scene's own triangles before comparing, so that a pose a few centimetres off does not read
// as range bias. Point-to-plane, with each point associated along its own beam (the beam is cast
// from the corrected pose; the residual is the distance from the measured point to the plane of
// the surface the beam meets), Gauss-Newton with robust weights, one rigid correction for the
// whole capture: world_corrected = correction * world.
#include <cstddef>
#include <memory>

#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

struct PoseRefinement {
  Pose correction;                                           // applied on the left of every pose
  Eigen::Vector3d sensor_shift_m = Eigen::Vector3d::Zero();  // how far the first column's sensor moved
  double rotation_deg = 0.0;                                 // the correction's rotation angle
  double rms_before_m = 0.0;  // point-to-plane residual of the points used, before and after
  double rms_after_m = 0.0;
  size_t points = 0;
  int iterations = 0;
};

struct RefineOptions {
  size_t max_points = 300'000;  // sampled evenly over the first frames' returns
  size_t max_frames = 20;
  double max_range_m = 100.0;   // where the cast stops looking
  double max_residual_m = 0.5;  // points farther than this from the surface their beam meets are left out
};

// Throws InputError when too few measured points meet the scene (under 100).
PoseRefinement refine_pose(const MeasuredCapture& capture, const Scene& scene, const PoseSource& poses,
                           double time_offset_s, const RefineOptions& options = {});

// A pose source moved by a rigid correction.
class CorrectedPoses final : public PoseSource {
 public:
  CorrectedPoses(const PoseSource& base, const Pose& correction) : base_(base), correction_(correction) {}
  Pose at(double time_s) const override;
  PoseSpan span() const override { return base_.span(); }
  double start_s() const override { return base_.start_s(); }

 private:
  const PoseSource& base_;
  Pose correction_;
};

}  // namespace lidartwin
