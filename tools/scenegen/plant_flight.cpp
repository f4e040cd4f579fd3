// The plant inspection flight (scenes/plant_inspection.tum), after the paper's closed benchmark
// trajectory around the refinery (Section IV, Fig. 4): one lap of a rounded rectangle (a
// superellipse |x/a|^6 + |y/b|^6 = 1, smooth everywhere) just inside the fence, at 4 m/s, climbing
// and descending between 6 and 18 m, heading along the path and banked as a multirotor must be
// to turn. Sampled at 20 Hz; the last pose equals the first.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "generators.h"

namespace lidartwin::scenegen {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kA = 152.0, kB = 100.0;      // half-extents of the loop, metres
constexpr double kSpeed = 4.0, kRate = 20.0;  // m/s, samples per second
constexpr double kGravity = 9.81;

Eigen::Vector2d loop_point(double theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  return {kA * std::cbrt(c), kB * std::cbrt(s)};
}

// Arc-length table of the loop, starting south of the centre and running anticlockwise.
struct ArcTable {
  std::vector<double> length;
  std::vector<Eigen::Vector2d> point;
  Eigen::Vector2d at(double s) const {
    const double total = length.back();
    s -= total * std::floor(s / total);
    const size_t i = static_cast<size_t>(std::upper_bound(length.begin(), length.end(), s) - length.begin());
    if (i >= length.size()) return point.back();
    const double u = (s - length[i - 1]) / (length[i] - length[i - 1]);
    return (1 - u) * point[i - 1] + u * point[i];
  }
};

ArcTable arc_table() {
  constexpr int kSteps = 400000;
  ArcTable table;
  for (int i = 0; i <= kSteps; ++i) {
    const Eigen::Vector2d p = loop_point(-kPi / 2 + 2 * kPi * i / kSteps);
    table.length.push_back(i == 0 ? 0.0 : table.length.back() + (p - table.point.back()).norm());
    table.point.push_back(p);
  }
  return table;
}

}  // namespace

std::vector<StampedPose> plant_inspection_flight() {
  const ArcTable loop = arc_table();
  const double total = loop.length.back();
  const int samples = static_cast<int>(std::round(total / kSpeed * kRate));
  const double step = total / samples;  // ≈ kSpeed / kRate, so the lap closes on a sample
  const double speed = step * kRate;
  std::vector<StampedPose> poses;
  double previous_yaw = 0.0;
  for (int k = 0; k <= samples; ++k) {
    const double s = step * k;
    const Eigen::Vector2d p = loop.at(s), ahead = loop.at(s + 1.0), behind = loop.at(s - 1.0);
    double yaw = std::atan2(ahead.y() - behind.y(), ahead.x() - behind.x());
    if (!poses.empty()) yaw = previous_yaw + std::remainder(yaw - previous_yaw, 2 * kPi);  // unwrapped: no flips
    previous_yaw = yaw;
    // Curvature: turn of the heading between chords whose midpoints are 1 m apart; bank so the
    // thrust supplies the centripetal v²κ.
    const Eigen::Vector2d t0 = (p - behind).normalized(), t1 = (ahead - p).normalized();
    const double curvature = std::atan2(t0.x() * t1.y() - t0.y() * t1.x(), t0.dot(t1));
    const double roll = -std::atan(speed * speed * curvature / kGravity);
    const double z = 12.0 + 6.0 * std::sin(2 * kPi * 2 * s / total);
    StampedPose pose;
    pose.time_s = k / kRate;
    pose.position = {p.x(), p.y(), z};
    pose.rotation =
        Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
    poses.push_back(pose);
  }
  poses.back().position = poses.front().position;  // close exactly, despite the table's rounding
  return poses;
}

void write_tum(const std::filesystem::path& path, const std::vector<StampedPose>& poses, const std::string& comment) {
  std::FILE* file = std::fopen(path.c_str(), "w");
  if (file == nullptr) throw std::runtime_error(path.string() + ": cannot open for writing");
  std::fprintf(file, "# %s\n# timestamp tx ty tz qx qy qz qw\n", comment.c_str());
  for (const StampedPose& pose : poses) {
    const Eigen::Quaterniond& q = pose.rotation;
    std::fprintf(file, "%.3f %.4f %.4f %.4f %.7f %.7f %.7f %.7f\n", pose.time_s, pose.position.x(), pose.position.y(),
                 pose.position.z(), q.x(), q.y(), q.z(), q.w());
  }
  if (std::fclose(file) != 0) throw std::runtime_error(path.string() + ": write failed");
}

}  // namespace lidartwin::scenegen
