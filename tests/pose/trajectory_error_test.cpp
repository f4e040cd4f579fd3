// Absolute pose error as evo computes it, on trajectories made here with a known truth: the
// alignment undoes a rigid (or similarity) transform, the statistics are those of the noise.
#include "lidartwin/pose/trajectory_error.h"

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/error.h"

namespace lidartwin {
namespace {

// A figure-of-eight flight, 100 poses at 10 Hz, not planar (so SE(3) alignment is determined).
std::vector<StampedPose> flight() {
  std::vector<StampedPose> poses;
  for (int k = 0; k < 100; ++k) {
    const double t = 0.1 * k;
    Pose p;
    p.translation = {10.0 * std::sin(0.3 * t), 5.0 * std::sin(0.6 * t), 2.0 + 0.5 * std::cos(0.4 * t)};
    p.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * t, Eigen::Vector3d::UnitZ()));
    poses.push_back({t, p});
  }
  return poses;
}

// estimate = scale * (R * reference + t) + noise, each position.
std::vector<StampedPose> moved(const std::vector<StampedPose>& reference, const Eigen::Matrix3d& r,
                               const Eigen::Vector3d& t, double scale, double noise_m, double dt_s = 0.0) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n(0.0, noise_m);
  std::vector<StampedPose> out = reference;
  for (StampedPose& p : out) {
    p.time_s += dt_s;
    p.pose.translation = scale * (r * p.pose.translation + t) + Eigen::Vector3d(n(rng), n(rng), n(rng));
  }
  return out;
}

const Eigen::Matrix3d kYaw30 = Eigen::AngleAxisd(std::numbers::pi / 6, Eigen::Vector3d::UnitZ()).toRotationMatrix();

TEST(AbsolutePoseError, Se3AlignmentLeavesOnlyTheNoise) {
  const auto reference = flight();
  const ApeResult r = absolute_pose_error(reference, moved(reference, kYaw30, {5, -3, 1}, 1.0, 0.01));
  EXPECT_EQ(r.pairs, 100u);
  // Isotropic 1 cm per axis: E|e|^2 = 3 sigma^2, less what the 6 alignment parameters absorb.
  EXPECT_NEAR(r.rmse_m, 0.01 * std::sqrt(3.0 * (100.0 - 2.0) / 100.0), 0.002);
  EXPECT_LE(r.min_m, r.median_m);
  EXPECT_LE(r.median_m, r.max_m);
  EXPECT_NEAR(r.rmse_m * r.rmse_m, r.mean_m * r.mean_m + r.std_m * r.std_m, 1e-12);
  // The alignment is the inverse of the move: reference_from_estimate.
  const Eigen::Matrix3d undo = r.alignment.rotation.toRotationMatrix() * kYaw30;
  EXPECT_LT(Eigen::AngleAxisd(undo).angle(), 0.001);
}

TEST(AbsolutePoseError, WithoutAlignmentAConstantOffsetIsTheError) {
  const auto reference = flight();
  ApeOptions options;
  options.alignment = Alignment::kNone;
  const ApeResult r =
      absolute_pose_error(reference, moved(reference, Eigen::Matrix3d::Identity(), {0.3, 0.4, 0}, 1.0, 0.0), options);
  EXPECT_NEAR(r.rmse_m, 0.5, 1e-12);
  EXPECT_NEAR(r.mean_m, 0.5, 1e-12);
  EXPECT_NEAR(r.std_m, 0.0, 1e-9);
  EXPECT_NEAR(r.median_m, 0.5, 1e-12);
}

TEST(AbsolutePoseError, Sim3RecoversTheScaleOfAMonocularEstimate) {
  const auto reference = flight();
  ApeOptions options;
  options.alignment = Alignment::kSim3;
  const ApeResult r = absolute_pose_error(reference, moved(reference, kYaw30, {1, 2, 3}, 0.5, 0.0), options);
  EXPECT_NEAR(r.scale, 2.0, 1e-9);
  EXPECT_LT(r.rmse_m, 1e-9);
  options.alignment = Alignment::kSe3;  // without scale, the halved flight cannot be matched
  EXPECT_GT(absolute_pose_error(reference, moved(reference, kYaw30, {1, 2, 3}, 0.5, 0.0), options).rmse_m, 1.0);
}

TEST(AbsolutePoseError, PairsAreAssociatedByTimestampWithinTheTolerance) {
  const auto reference = flight();
  const auto late = moved(reference, Eigen::Matrix3d::Identity(), {0, 0, 0}, 1.0, 0.0, 0.004);
  EXPECT_EQ(absolute_pose_error(reference, late).pairs, 100u);
  const auto later = moved(reference, Eigen::Matrix3d::Identity(), {0, 0, 0}, 1.0, 0.0, 0.02);
  EXPECT_THROW(absolute_pose_error(reference, later), InputError);
  ApeOptions shifted;
  shifted.time_offset_s = -0.02;  // evo's --t_offset
  EXPECT_EQ(absolute_pose_error(reference, later, shifted).pairs, 100u);
}

TEST(AbsolutePoseError, MedianOfAnEvenCountIsTheMeanOfTheMiddleTwoAsNumpy) {
  std::vector<StampedPose> reference, estimate;
  const double offsets[] = {0.1, 0.4, 0.2, 0.3};
  for (int k = 0; k < 4; ++k) {
    Pose p;
    p.translation = {static_cast<double>(k), 0, 0};
    reference.push_back({static_cast<double>(k), p});
    p.translation.y() = offsets[k];
    estimate.push_back({static_cast<double>(k), p});
  }
  ApeOptions options;
  options.alignment = Alignment::kNone;
  const ApeResult r = absolute_pose_error(reference, estimate, options);
  EXPECT_NEAR(r.median_m, 0.25, 1e-12);
  EXPECT_NEAR(r.rmse_m, std::sqrt((0.01 + 0.16 + 0.04 + 0.09) / 4), 1e-12);
  EXPECT_NEAR(r.min_m, 0.1, 1e-12);
  EXPECT_NEAR(r.max_m, 0.4, 1e-12);
}

}  // namespace
}  // namespace lidartwin
