#pragma once
// Poses of the sensor in the scene's world frame (Z up, metres; see scene/scene.h).
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

namespace lidartwin {

// world_from_sensor: maps a point in the Ouster sensor frame to the world frame.
struct Pose {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return rotation * p + translation; }
  // Composition: (a_from_b * b_from_c) is a_from_c.
  Pose operator*(const Pose& b) const { return {rotation * b.rotation, rotation * b.translation + translation}; }
};
std::string to_string(const Pose& pose);
// "x y z qx qy qz qw" (TUM order). Throws InputError naming the text and the problem.
Pose parse_pose(std::string_view text);

struct StampedPose {
  double time_s = 0.0;
  Pose pose;
};

// One layout in every translation unit (cmake/InstructionSet.cmake): Eigen sizes and aligns
// Quaterniond by the vector width a unit is compiled for, and a unit built for AVX once saw
// StampedPose as 96 bytes where the rest of the program saw 80. A unit that disagrees fails here.
static_assert(alignof(Eigen::Quaterniond) == 16 && sizeof(Eigen::Quaterniond) == 32);
static_assert(alignof(Pose) == 16 && sizeof(Pose) == 64);
static_assert(alignof(StampedPose) == 16 && sizeof(StampedPose) == 80);

// A trajectory: linear interpolation of translation and slerp of rotation between samples.
// A looping trajectory repeats with period (end - start); otherwise it holds its end poses.
class Trajectory {
 public:
  static Trajectory constant(const Pose& pose);
  // TUM format: "timestamp tx ty tz qx qy qz qw" per line, '#' comments. Throws InputError naming
  // the file and line of a bad row, or non-increasing times.
  static Trajectory load_tum(const std::filesystem::path& path, bool loop = true);
  explicit Trajectory(std::vector<StampedPose> samples, bool loop = true);

  Pose at(double time_s) const;
  double start_s() const;
  double duration_s() const;
  const std::vector<StampedPose>& samples() const { return samples_; }
  void save_tum(const std::filesystem::path& path) const;

 private:
  std::vector<StampedPose> samples_;
  bool loop_ = true;
};

void write_tum(const std::filesystem::path& path, const std::vector<StampedPose>& poses);

// One TUM row, "%.9f %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n" of time, translation and
// quaternion (x y z w), as TumWriter and write_tum write them; the rows of a file follow kTumHeader.
struct TumRow {
  std::array<char, 8 * 324> text;  // room for any doubles: 309 integer digits, sign, point, 12 decimals, separator
  size_t size = 0;
  std::string_view view() const { return {text.data(), size}; }
};
TumRow tum_row(double time_s, const Pose& pose);
inline constexpr std::string_view kTumHeader = "# timestamp tx ty tz qx qy qz qw\n";

// A TUM file written row by row (a daemon's ground truth grows while it streams). Throws
// InputError naming the file if it cannot be created; close() reports a failed write.
class TumWriter {
 public:
  explicit TumWriter(const std::filesystem::path& path);
  ~TumWriter();
  TumWriter(const TumWriter&) = delete;
  TumWriter& operator=(const TumWriter&) = delete;
  void write(double time_s, const Pose& pose);
  void close();

 private:
  std::filesystem::path path_;
  std::FILE* file_ = nullptr;
};

}  // namespace lidartwin
