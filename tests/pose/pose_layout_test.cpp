// The shared pose types have one layout in every translation unit (cmake/InstructionSet.cmake):
// this baseline unit and every Highway target's region agree, printed so a failure shows which.
#include <cstdio>

#include <gtest/gtest.h>

#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_source.h"
#include "pose/pose_layout.h"

namespace lidartwin::test {
namespace {

PoseLayouts baseline_layouts() {
  PoseLayouts out;
  out.size = {sizeof(Pose), sizeof(StampedPose), sizeof(StaticPose), sizeof(MountedPoses)};
  out.align = {alignof(Pose), alignof(StampedPose), alignof(StaticPose), alignof(MountedPoses)};
  return out;
}

void print(const char* unit, const PoseLayouts& layouts) {
  std::printf("%-22s", unit);
  for (size_t i = 0; i < kPoseTypeNames.size(); ++i) {
    std::printf("  %s %zu/%zu", kPoseTypeNames[i], layouts.size[i], layouts.align[i]);
  }
  std::printf("\n");
}

TEST(PoseLayout, IsTheSameInTheBaselineUnitAndEveryHighwayTarget) {
  const PoseLayouts baseline = baseline_layouts();
  std::printf("sizeof/alignof in bytes\n");
  print("baseline unit", baseline);
  // The values pose.h asserts: Eigen's 16-byte Quaterniond alignment on every target.
  EXPECT_EQ(baseline.size, (std::array<size_t, 4>{64, 80, 80, 80}));
  EXPECT_EQ(baseline.align, (std::array<size_t, 4>{16, 16, 16, 16}));
  const auto targets = pose_layouts_per_target();
  ASSERT_FALSE(targets.empty());
  for (const auto& [target, compiled, layouts] : targets) {
    print(("Highway " + target).c_str(), layouts);
    EXPECT_EQ(compiled, target) << "the dispatch did not reach the target's own code";
    EXPECT_EQ(layouts, baseline) << "Highway target " << target;
  }
}

}  // namespace
}  // namespace lidartwin::test
