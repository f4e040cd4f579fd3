#pragma once
// One ray into a Scene with rtcIntersect1, for scene tests: the first hit or nothing.
#include <limits>
#include <optional>

#include <embree3/rtcore.h>

#include "lidartwin/scene/scene.h"

namespace lidartwin::test {

struct Hit {
  float distance;
  unsigned geom_id;
  unsigned prim_id;
  Eigen::Vector3f normal;  // Embree's geometric normal, world frame
};

inline std::optional<Hit> cast(const Scene& scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                               float horizon = std::numeric_limits<float>::infinity()) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(origin.x());
  rh.ray.org_y = static_cast<float>(origin.y());
  rh.ray.org_z = static_cast<float>(origin.z());
  rh.ray.dir_x = static_cast<float>(direction.x());
  rh.ray.dir_y = static_cast<float>(direction.y());
  rh.ray.dir_z = static_cast<float>(direction.z());
  rh.ray.tfar = horizon;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene.embree_scene(), &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  return Hit{rh.ray.tfar, rh.hit.geomID, rh.hit.primID, Eigen::Vector3f(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z)};
}

}  // namespace lidartwin::test
