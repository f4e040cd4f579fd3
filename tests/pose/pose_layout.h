#pragma once
// The layout of the shared pose types as one translation unit sees it (pose_layout_test.cpp).
#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace lidartwin::test {

// sizeof and alignof of Pose, StampedPose, StaticPose and MountedPoses, in that order.
struct PoseLayouts {
  std::array<size_t, 4> size{};
  std::array<size_t, 4> align{};
  friend bool operator==(const PoseLayouts&, const PoseLayouts&) = default;
};
inline constexpr std::array<const char*, 4> kPoseTypeNames{"Pose", "StampedPose", "StaticPose", "MountedPoses"};

struct TargetPoseLayouts {
  std::string target;    // the target dispatched to, Highway's name: "AVX2", "SSE4", "EMU128"...
  std::string compiled;  // HWY_TARGET where the measuring code was compiled: the same if it ran there
  PoseLayouts layouts;
};
// Measured inside each Highway target's region of pose_layout_targets.cpp (compiled with that
// target's instruction set on), for every target Highway compiled that this CPU runs.
std::vector<TargetPoseLayouts> pose_layouts_per_target();

}  // namespace lidartwin::test
