// Clearance of a trajectory in a scene, cast with Embree through the scene module (so the check
// sees exactly what the emulator will see).
#include "flight_check.h"

#include <algorithm>

#include "lidartwin/scene/scene.h"

namespace lidartwin::scenegen {
namespace {

std::vector<Eigen::Vector3d> directions() {
  std::vector<Eigen::Vector3d> out;
  for (int x = -1; x <= 1; ++x) {
    for (int y = -1; y <= 1; ++y) {
      for (int z = -1; z <= 1; ++z) {
        if (x != 0 || y != 0 || z != 0) out.push_back(Eigen::Vector3d(x, y, z).normalized());
      }
    }
  }
  return out;
}

}  // namespace

Clearance min_clearance(const std::filesystem::path& scene_path, const std::vector<StampedPose>& poses,
                        double horizon_m) {
  const Scene scene = Scene::load(scene_path);
  Clearance clearance{horizon_m, poses.front().position};
  for (const StampedPose& pose : poses) {
    for (const Eigen::Vector3d& d : directions()) {
      const auto hit = scene.first_hit(pose.position, d, 0.0f, static_cast<float>(horizon_m));
      const double distance = hit ? static_cast<double>(hit->distance) : horizon_m;
      if (distance < clearance.distance_m) clearance = {distance, pose.position};
    }
  }
  return clearance;
}

}  // namespace lidartwin::scenegen
