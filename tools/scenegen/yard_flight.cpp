// The SLAM lap over the yard (scenes/yard_flight.tum): the drone rests on the pad, takes off
// (climbing to 5 m while it accelerates to 4 m/s along the lap), flies one lap of a rounded
// rectangle (|x/a|^4 + |y/b|^4 = 1) heading along the path and banked into the turns, slows to a
// stop over the pad and hovers. Starting from rest, the odometry's constant-velocity prior is
// right from the first frame. Sampled at 20 Hz.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "generators.h"

namespace lidartwin::scenegen {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kA = 28.0, kB = 18.0;  // half-extents of the lap, metres
constexpr double kCruise = 4.0;         // m/s
constexpr double kRamp = 4.0;           // s to reach cruise speed, and to stop
constexpr double kRest = 1.0;           // s on the pad before take-off and hovering at the end
constexpr double kPadHeight = 0.6, kHeight = 5.0;
constexpr double kRate = 20.0, kGravity = 9.81;

double signed_root(double v, double p) { return std::copysign(std::pow(std::abs(v), p), v); }

// Arc-length table of the lap, starting at the pad (0, -kB) and running anticlockwise.
struct Lap {
  std::vector<double> length;
  std::vector<Eigen::Vector2d> point;
  Lap() {
    constexpr int kSteps = 200000;
    for (int i = 0; i <= kSteps; ++i) {
      const double t = -kPi / 2 + 2 * kPi * i / kSteps;
      const Eigen::Vector2d p(kA * signed_root(std::cos(t), 0.5), kB * signed_root(std::sin(t), 0.5));
      length.push_back(i == 0 ? 0.0 : length.back() + (p - point.back()).norm());
      point.push_back(p);
    }
  }
  double total() const { return length.back(); }
  Eigen::Vector2d at(double s) const {
    s -= total() * std::floor(s / total());
    const auto i = static_cast<size_t>(std::upper_bound(length.begin(), length.end(), s) - length.begin());
    if (i >= length.size()) return point.back();
    const double u = (s - length[i - 1]) / (length[i] - length[i - 1]);
    return (1 - u) * point[i - 1] + u * point[i];
  }
};

// Smooth 0 -> 1 over [0, 1] with zero slope at both ends.
double smoothstep(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * (3 - 2 * u);
}

}  // namespace

std::vector<StampedPose> yard_flight() {
  const Lap lap;
  // Distance along the lap: speed ramps up from rest over kRamp (covering kCruise * kRamp / 2, as
  // smoothstep averages one half), cruises, and ramps down to stop exactly one lap on.
  const double ramp_distance = kCruise * kRamp / 2;
  const double cruise_time = (lap.total() - 2 * ramp_distance) / kCruise;
  const double take_off = kRest, cruise_from = take_off + kRamp, stop_from = cruise_from + cruise_time;
  const double end = stop_from + kRamp + kRest;
  // Integrated with a fine step; speed(t) is the smoothstep ramps.
  const auto speed = [&](double t) {
    if (t < take_off || t > stop_from + kRamp) return 0.0;
    if (t < cruise_from) return kCruise * smoothstep((t - take_off) / kRamp);
    if (t < stop_from) return kCruise;
    return kCruise * (1.0 - smoothstep((t - stop_from) / kRamp));
  };
  std::vector<StampedPose> poses;
  double s = 0.0, t = 0.0, previous_yaw = 0.0;
  constexpr double kStep = 1e-4;
  for (int k = 0; k / kRate <= end + 1e-9; ++k) {
    const double sample_t = k / kRate;
    for (; t < sample_t - 1e-12; t += kStep) s += kStep * speed(t + kStep / 2);
    const Eigen::Vector2d p = lap.at(s), ahead = lap.at(s + 1.0), behind = lap.at(s - 1.0);
    double yaw = std::atan2(ahead.y() - behind.y(), ahead.x() - behind.x());
    if (!poses.empty()) yaw = previous_yaw + std::remainder(yaw - previous_yaw, 2 * kPi);
    previous_yaw = yaw;
    const Eigen::Vector2d t0 = (p - behind).normalized(), t1 = (ahead - p).normalized();
    const double curvature = std::atan2(t0.x() * t1.y() - t0.y() * t1.x(), t0.dot(t1));
    const double v = speed(sample_t);
    const double roll = -std::atan(v * v * curvature / kGravity);
    const double climb = smoothstep((sample_t - take_off) / kRamp);
    StampedPose pose;
    pose.time_s = sample_t;
    pose.position = {p.x(), p.y(), kPadHeight + (kHeight - kPadHeight) * climb};
    pose.rotation =
        Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
    poses.push_back(pose);
  }
  return poses;
}

}  // namespace lidartwin::scenegen
