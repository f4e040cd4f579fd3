// Pose parsing, TUM files and interpolation, checked against closed forms.
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "lidartwin/error.h"
#include "lidartwin/pose/pose.h"

namespace lidartwin {
namespace {

using ::testing::HasSubstr;

std::filesystem::path temp_file(const std::string& name, const std::string& contents) {
  const auto dir = std::filesystem::temp_directory_path() / ("lidartwin_pose_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto path = dir / name;
  std::ofstream(path) << contents;
  return path;
}

std::string error_of(auto&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

Eigen::Quaterniond about_z(double angle) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
}

TEST(Pose, ParsesTumOrderAndNormalizesTheQuaternion) {
  const Pose pose = parse_pose("1 2 3  0 0 2 2");
  EXPECT_EQ(pose.translation, Eigen::Vector3d(1, 2, 3));
  EXPECT_NEAR(pose.rotation.norm(), 1.0, 1e-15);
  EXPECT_NEAR(pose.rotation.z(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(pose.rotation.w(), std::sqrt(0.5), 1e-15);
  // 90 degrees about z: sensor +X maps to world +Y, then translated.
  const Eigen::Vector3d p = pose * Eigen::Vector3d(1, 0, 0);
  EXPECT_NEAR((p - Eigen::Vector3d(1, 3, 3)).norm(), 0.0, 1e-12);
}

TEST(Pose, RejectsBadTextNamingIt) {
  EXPECT_THAT(error_of([] { parse_pose("1 2 3 0 0 0"); }), HasSubstr("\"1 2 3 0 0 0\""));
  EXPECT_THAT(error_of([] { parse_pose("1 2 3 0 0 0"); }), HasSubstr("got 6"));
  EXPECT_THAT(error_of([] { parse_pose("1 2 x 0 0 0 1"); }), HasSubstr("non-number"));
  EXPECT_THAT(error_of([] { parse_pose("1 2 3 0 0 0 0"); }), HasSubstr("zero norm"));
  EXPECT_THAT(error_of([] { parse_pose("1 nan 3 0 0 0 1"); }), HasSubstr("finite"));
  EXPECT_THAT(error_of([] { parse_pose("1 2 3 0 0 inf 1"); }), HasSubstr("\"1 2 3 0 0 inf 1\""));
}

TEST(Pose, ToStringRoundTrips) {
  Pose pose;
  pose.translation = {1.5, -2.25, 3.125};
  pose.rotation = about_z(0.3);
  const Pose back = parse_pose(to_string(pose));
  EXPECT_NEAR((back.translation - pose.translation).norm(), 0.0, 1e-8);
  EXPECT_NEAR(back.rotation.angularDistance(pose.rotation), 0.0, 1e-8);
}

Trajectory two_samples(bool loop) {
  Pose a, b;
  b.translation = {10, 0, 0};
  b.rotation = about_z(std::numbers::pi / 2);
  return Trajectory({{1.0, a}, {3.0, b}}, loop);
}

TEST(Trajectory, LerpsTranslationAndSlerpsRotation) {
  const Trajectory trajectory = two_samples(false);
  const Pose mid = trajectory.at(1.5);  // a quarter of the way
  EXPECT_NEAR((mid.translation - Eigen::Vector3d(2.5, 0, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(mid.rotation.angularDistance(about_z(std::numbers::pi / 8)), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(trajectory.start_s(), 1.0);
  EXPECT_DOUBLE_EQ(trajectory.duration_s(), 2.0);
}

TEST(Trajectory, HoldsEndPosesWithoutLooping) {
  const Trajectory trajectory = two_samples(false);
  EXPECT_EQ(trajectory.at(-5.0).translation, Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(trajectory.at(50.0).translation, Eigen::Vector3d(10, 0, 0));
}

TEST(Trajectory, LoopsWithItsDuration) {
  const Trajectory trajectory = two_samples(true);
  for (double t : {1.5, 2.0, 2.75}) {
    EXPECT_NEAR((trajectory.at(t + 2.0).translation - trajectory.at(t).translation).norm(), 0.0, 1e-9) << t;
    EXPECT_NEAR((trajectory.at(t - 4.0).translation - trajectory.at(t).translation).norm(), 0.0, 1e-9) << t;
  }
}

TEST(Trajectory, SlerpTakesTheShortArc) {
  Pose a, b;
  b.rotation = Eigen::Quaterniond(-about_z(0.2).coeffs());  // same rotation, opposite sign
  const Trajectory trajectory({{0.0, a}, {1.0, b}}, false);
  EXPECT_NEAR(trajectory.at(0.5).rotation.angularDistance(about_z(0.1)), 0.0, 1e-12);
}

TEST(Trajectory, ConstantIsTheSameEverywhere) {
  const Pose pose = parse_pose("1 2 3 0 0 0 1");
  const Trajectory trajectory = Trajectory::constant(pose);
  EXPECT_EQ(trajectory.at(-1e6).translation, pose.translation);
  EXPECT_EQ(trajectory.at(1e6).translation, pose.translation);
}

TEST(Trajectory, TumRoundTrip) {
  const Trajectory trajectory = two_samples(false);
  const auto path = temp_file("round_trip.tum", "");
  trajectory.save_tum(path);
  const Trajectory back = Trajectory::load_tum(path, false);
  ASSERT_EQ(back.samples().size(), 2u);
  for (double t : {0.0, 1.3, 2.2, 3.0}) {
    EXPECT_NEAR((back.at(t).translation - trajectory.at(t).translation).norm(), 0.0, 1e-9);
    EXPECT_NEAR(back.at(t).rotation.angularDistance(trajectory.at(t).rotation), 0.0, 1e-9);
  }
}

// TUM rows carry printf's "%.9f" (time, position) and "%.12f" (quaternion) digits, whatever the
// magnitude: values near rounding ties, tiny negatives ("-0.000..."), and large ones.
TEST(Trajectory, TumRowsHavePrintfsDigits) {
  std::mt19937_64 rng(20261125);
  std::vector<std::array<double, 8>> rows;
  for (int i = 0; i < 2000; ++i) {
    std::array<double, 8> row{};
    for (double& v : row) {
      const double mantissa = std::uniform_real_distribution<double>(-1.0, 1.0)(rng);
      v = std::ldexp(mantissa, std::uniform_int_distribution<int>(-50, 40)(rng));
    }
    rows.push_back(row);
  }
  rows.push_back({0.5e-9, -0.5e-9, 1.5e-9, 2.5e-9, 0.5e-12, -1.5e-12, -0.0, 1.0});
  rows.push_back({1.0000000005, 123456.7890123455, -2.0000000015, 1e30, 0.9999999999995, -0.25, 0.125, 5e-13});
  const auto path = temp_file("digits.tum", "");
  {
    TumWriter writer(path);
    for (const auto& r : rows) writer.write(r[0], Pose{Eigen::Quaterniond(r[7], r[4], r[5], r[6]), {r[1], r[2], r[3]}});
    writer.close();
  }
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // the header
  for (const auto& r : rows) {
    char expected[8 * 400];
    std::snprintf(expected, sizeof expected, "%.9f %.9f %.9f %.9f %.12f %.12f %.12f %.12f", r[0], r[1], r[2], r[3],
                  r[4], r[5], r[6], r[7]);
    ASSERT_TRUE(std::getline(in, line));
    EXPECT_EQ(line, expected);
  }
}

TEST(Trajectory, TumSkipsCommentsAndBlankLines) {
  const auto path =
      temp_file("comments.tum", "# timestamp tx ty tz qx qy qz qw\n\n0 0 0 0 0 0 0 1\n  1 1 0 0 0 0 0 1\n");
  EXPECT_EQ(Trajectory::load_tum(path).samples().size(), 2u);
}

TEST(Trajectory, TumErrorsNameFileAndLine) {
  const auto bad_row = temp_file("bad_row.tum", "# c\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n");
  EXPECT_THAT(error_of([&] { Trajectory::load_tum(bad_row); }), HasSubstr(bad_row.string() + ":3:"));
  const auto backwards = temp_file("backwards.tum", "0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n");
  EXPECT_THAT(error_of([&] { Trajectory::load_tum(backwards); }), HasSubstr(backwards.string() + ":3:"));
  EXPECT_THAT(error_of([&] { Trajectory::load_tum(backwards); }), HasSubstr("not after"));
  const auto zero_q = temp_file("zero_q.tum", "0 0 0 0 0 0 0 0\n");
  EXPECT_THAT(error_of([&] { Trajectory::load_tum(zero_q); }), HasSubstr(zero_q.string() + ":1:"));
  const auto empty = temp_file("empty.tum", "# nothing\n");
  EXPECT_THAT(error_of([&] { Trajectory::load_tum(empty); }), HasSubstr("no poses"));
  EXPECT_THAT(error_of([] { Trajectory::load_tum("/nonexistent/x.tum"); }), HasSubstr("/nonexistent/x.tum"));
}

TEST(Trajectory, ConstructorRejectsNonIncreasingTimes) {
  EXPECT_THROW(Trajectory({{1.0, Pose{}}, {1.0, Pose{}}}), InputError);
  EXPECT_THROW(Trajectory({}), InputError);
}

}  // namespace
}  // namespace lidartwin
