#pragma once
// sensor_from_world from world_from_sensor: what the ground-truth tests need to take a mounting off
// a recorded pose.
#include "lidartwin/pose/pose.h"

namespace lidartwin::test {

inline Pose inverse(const Pose& p) {
  const Eigen::Quaterniond r = p.rotation.conjugate();
  return {r, -(r * p.translation)};
}

}  // namespace lidartwin::test
