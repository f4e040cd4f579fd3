#pragma once
// One ray into a Scene for scene tests: the first hit or nothing (Scene::first_hit).
#include <limits>
#include <optional>

#include "lidartwin/scene/scene.h"

namespace lidartwin::test {

inline std::optional<SceneHit> cast(const Scene& scene, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                    float horizon = std::numeric_limits<float>::infinity()) {
  return scene.first_hit(origin, direction, 0.0f, horizon);
}

}  // namespace lidartwin::test
