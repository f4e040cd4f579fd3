#pragma once
// Checks a generated trajectory against the generated scene: the drone must keep its distance.
#include <filesystem>
#include <vector>

#include "generators.h"

namespace lidartwin::scenegen {

struct Clearance {
  double distance_m;      // smallest distance from a pose to a surface (capped at the horizon)
  Eigen::Vector3d where;  // the pose where it occurs
};

// Rays in 26 directions from every pose, up to `horizon_m`.
Clearance min_clearance(const std::filesystem::path& scene, const std::vector<StampedPose>& poses, double horizon_m);

}  // namespace lidartwin::scenegen
