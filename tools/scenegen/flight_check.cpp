// Clearance of a trajectory in a scene, cast with Embree through the scene module (so the check
// sees exactly what the emulator will see).
#include "flight_check.h"

#include <algorithm>

#include <embree3/rtcore.h>

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

double first_hit(RTCScene scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double horizon) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(origin.x());
  rh.ray.org_y = static_cast<float>(origin.y());
  rh.ray.org_z = static_cast<float>(origin.z());
  rh.ray.dir_x = static_cast<float>(direction.x());
  rh.ray.dir_y = static_cast<float>(direction.y());
  rh.ray.dir_z = static_cast<float>(direction.z());
  rh.ray.tfar = static_cast<float>(horizon);
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &context, &rh);
  return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? horizon : static_cast<double>(rh.ray.tfar);
}

}  // namespace

Clearance min_clearance(const std::filesystem::path& scene_path, const std::vector<StampedPose>& poses,
                        double horizon_m) {
  const Scene scene = Scene::load(scene_path);
  Clearance clearance{horizon_m, poses.front().position};
  for (const StampedPose& pose : poses) {
    for (const Eigen::Vector3d& d : directions()) {
      const double distance = first_hit(scene.embree_scene(), pose.position, d, horizon_m);
      if (distance < clearance.distance_m) clearance = {distance, pose.position};
    }
  }
  return clearance;
}

}  // namespace lidartwin::scenegen
