// Point-to-plane registration of a capture to its scene, associating each point along its beam.
#include "lidartwin/analysis/pose_refinement.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <vector>

#include <fmt/format.h>
#include <Eigen/Dense>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/error.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin {
namespace {

constexpr int kMaxIterations = 30;
constexpr size_t kMinPoints = 100;

struct Sample {
  double time_s;
  int row, column;
  double range_mm;
};

std::vector<Sample> sample_returns(const MeasuredCapture& capture, const RefineOptions& options) {
  const size_t frames = std::min(options.max_frames, capture.frames.size());
  size_t returns = 0;
  for (size_t f = 0; f < frames; ++f) {
    for (const uint32_t mm : capture.frames[f].scan.channels[static_cast<int>(ChannelField::kRange)]) returns += mm > 0;
  }
  const size_t stride = std::max<size_t>(1, returns / options.max_points);
  std::vector<Sample> samples;
  size_t seen = 0;
  for (size_t f = 0; f < frames; ++f) {
    const Scan& scan = capture.frames[f].scan;
    for (int m = 0; m < scan.width; ++m) {
      for (int r = 0; r < scan.height; ++r) {
        const uint32_t mm = scan.at(ChannelField::kRange, m, r);
        if (mm == 0 || seen++ % stride != 0) continue;
        samples.push_back(
            {static_cast<double>(scan.timestamp_ns[static_cast<size_t>(m)]) * 1e-9, r, m, static_cast<double>(mm)});
      }
    }
  }
  return samples;
}

}  // namespace

Pose CorrectedPoses::at(double time_s) const { return correction_ * base_.at(time_s); }

PoseRefinement refine_pose(const MeasuredCapture& capture, const Scene& scene, const PoseSource& poses,
                           double time_offset_s, const RefineOptions& options) {
  const Metadata& metadata = capture.metadata;
  const BeamGeometry geometry(metadata.beams, metadata.format.columns_per_frame);
  const std::vector<Sample> samples = sample_returns(capture, options);
  // Each sample's pose and its point and beam in the world, before any correction.
  struct Point {
    Eigen::Vector3d point, origin, direction;
    float near_m;
  };
  std::vector<Point> points;
  points.reserve(samples.size());
  for (const Sample& s : samples) {
    const Pose pose = poses.at(s.time_s + time_offset_s);
    const BeamRay& ray = geometry.ray(s.row, s.column);
    points.push_back({pose * geometry.point(s.row, s.column, s.range_mm), pose * ray.origin_m.cast<double>(),
                      pose.rotation * ray.direction.cast<double>(), ray.range_offset_m});
  }
  // Rotations are taken about the points' centroid, where they barely move the cloud's centre:
  // about the world origin, a rotation and a translation far from it would fight each other.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Point& p : points) centre += p.point;
  centre /= static_cast<double>(std::max<size_t>(points.size(), 1));

  Pose correction;
  PoseRefinement result;
  const auto far = static_cast<float>(options.max_range_m + 1.0);
  for (int iteration = 0; iteration <= kMaxIterations; ++iteration) {
    Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> gradient = Eigen::Matrix<double, 6, 1>::Zero();
    std::vector<double> residuals;
    residuals.reserve(points.size());
    struct Row {
      Eigen::Matrix<double, 6, 1> jacobian;
      double residual;
    };
    std::vector<Row> rows;
    rows.reserve(points.size());
    for (const Point& p : points) {
      const Eigen::Vector3d origin = correction * p.origin;
      const Eigen::Vector3d direction = correction.rotation * p.direction;
      const std::optional<SceneHit> hit = scene.first_hit(origin, direction, p.near_m, far);
      if (!hit) continue;
      const Eigen::Vector3d n = hit->normal.cast<double>().normalized();
      if (!n.allFinite()) continue;
      const Eigen::Vector3d surface = origin + static_cast<double>(hit->distance) * direction;
      const Eigen::Vector3d point = correction * p.point;
      const double residual = n.dot(point - surface);
      if (std::abs(residual) > options.max_residual_m) continue;
      Row row;
      row.jacobian << (point - centre).cross(n), n;
      row.residual = residual;
      rows.push_back(row);
      residuals.push_back(std::abs(residual));
    }
    if (rows.size() < kMinPoints) {
      throw InputError(
          fmt::format("--refine-pose: only {} of {} measured points lie within {} m of a surface of the "
                      "scene their beam meets; the pose is too far off (or the scene is not the measured "
                      "place) to register",
                      rows.size(), points.size(), options.max_residual_m));
    }
    // Huber weights at 2 robust sigmas (1.4826 MAD): edges and clutter the scene lacks weigh less.
    std::nth_element(residuals.begin(), residuals.begin() + static_cast<std::ptrdiff_t>(residuals.size() / 2),
                     residuals.end());
    const double k = std::max(2.0 * 1.4826 * residuals[residuals.size() / 2], 1e-4);
    double sum2 = 0.0;
    for (const Row& row : rows) {
      const double w = std::abs(row.residual) <= k ? 1.0 : k / std::abs(row.residual);
      normal += w * row.jacobian * row.jacobian.transpose();
      gradient += w * row.jacobian * row.residual;
      sum2 += row.residual * row.residual;
    }
    const double rms = std::sqrt(sum2 / static_cast<double>(rows.size()));
    if (iteration == 0) result.rms_before_m = rms;
    result.rms_after_m = rms;
    result.points = rows.size();
    result.iterations = iteration;
    if (iteration == kMaxIterations) break;
    const Eigen::Matrix<double, 6, 1> step = normal.ldlt().solve(-gradient);
    const Eigen::Vector3d omega = step.head<3>();
    const double angle = omega.norm();
    const Eigen::Quaterniond rotation =
        angle > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle)) : Eigen::Quaterniond::Identity();
    // p -> R (p - c) + c + tau, composed on the left of the correction so far.
    const Pose update{rotation, centre - rotation * centre + step.tail<3>()};
    correction = update * correction;
    correction.rotation.normalize();
    if (angle < 1e-9 && step.tail<3>().norm() < 1e-7) break;
  }
  result.correction = correction;
  const Pose first = poses.at(samples.front().time_s + time_offset_s);
  result.sensor_shift_m = (correction * first).translation - first.translation;
  result.rotation_deg = Eigen::AngleAxisd(correction.rotation).angle() * 180.0 / std::numbers::pi;
  return result;
}

}  // namespace lidartwin
