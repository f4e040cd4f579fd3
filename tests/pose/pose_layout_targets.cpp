// The pose types measured once per Highway target: foreach_target.h compiles this file again for
// each, with the target's instruction set on in the HWY_NAMESPACE region (GCC's target pragma), as
// the per-pixel kernels are compiled.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "pose/pose_layout_targets.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/highway.h>

#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_source.h"
#include "pose/pose_layout.h"

HWY_BEFORE_NAMESPACE();
namespace lidartwin::test::HWY_NAMESPACE {

TargetPoseLayouts MeasurePoseLayouts() {
  TargetPoseLayouts out;
  out.compiled = hwy::TargetName(HWY_TARGET);
  out.layouts.size = {sizeof(Pose), sizeof(StampedPose), sizeof(StaticPose), sizeof(MountedPoses)};
  out.layouts.align = {alignof(Pose), alignof(StampedPose), alignof(StaticPose), alignof(MountedPoses)};
  return out;
}

}  // namespace lidartwin::test::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lidartwin::test {

HWY_EXPORT(MeasurePoseLayouts);

std::vector<TargetPoseLayouts> pose_layouts_per_target() {
  std::vector<TargetPoseLayouts> out;
  for (const int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    out.push_back(HWY_DYNAMIC_DISPATCH(MeasurePoseLayouts)());
    out.back().target = hwy::TargetName(target);
  }
  hwy::SetSupportedTargetsForTest(0);  // back to what the CPU supports
  return out;
}

}  // namespace lidartwin::test
#endif  // HWY_ONCE
