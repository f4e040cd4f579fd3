#pragma once
// Absolute pose error of an estimated trajectory against ground truth, computed as evo's `evo_ape`
// does for its translation part (the paper's Table II): associate the poses by timestamp, align
// the estimate to the reference with Umeyama's least-squares SE(3) (or Sim(3), with scale), then
// the statistics of the translation errors.
#include <string>
#include <vector>

#include "lidartwin/pose/pose.h"

namespace lidartwin {

enum class Alignment { kNone, kSe3, kSim3 };

struct ApeOptions {
  double max_time_difference_s = 0.01;  // evo's --t_max_diff default
  double time_offset_s = 0.0;           // added to the estimate's stamps (evo's --t_offset)
  Alignment alignment = Alignment::kSe3;
};

struct ApeResult {
  size_t pairs = 0;
  double rmse_m = 0.0, mean_m = 0.0, median_m = 0.0, std_m = 0.0, min_m = 0.0, max_m = 0.0;
  Pose alignment;                // reference_from_estimate (rotation, translation)
  double scale = 1.0;            // Sim(3) only
  std::vector<double> times_s;   // reference stamps of the pairs
  std::vector<double> errors_m;  // translation error per pair
};

// Throws InputError when fewer than 3 pairs associate (alignment needs them) or the alignment is
// degenerate (all positions on a line).
ApeResult absolute_pose_error(const std::vector<StampedPose>& reference, const std::vector<StampedPose>& estimate,
                              const ApeOptions& options = {});

}  // namespace lidartwin
