// APE as evo computes it: timestamp association, Umeyama alignment, translation error statistics.
#include "lidartwin/pose/trajectory_error.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "lidartwin/error.h"

namespace lidartwin {
namespace {

// evo's associate_trajectories: for each estimate stamp (both sorted), the nearest reference stamp
// within the tolerance; each reference pose is used once.
std::vector<std::pair<size_t, size_t>> associate(const std::vector<StampedPose>& reference,
                                                 const std::vector<StampedPose>& estimate, const ApeOptions& options) {
  std::vector<std::pair<size_t, size_t>> pairs;
  std::vector<uint8_t> used(reference.size(), 0);
  for (size_t e = 0; e < estimate.size(); ++e) {
    const double t = estimate[e].time_s + options.time_offset_s;
    const auto it = std::lower_bound(reference.begin(), reference.end(), t,
                                     [](const StampedPose& p, double time) { return p.time_s < time; });
    size_t best = reference.size();
    double best_dt = options.max_time_difference_s;
    for (auto candidate : {it, it == reference.begin() ? it : it - 1}) {
      if (candidate == reference.end()) continue;
      const auto r = static_cast<size_t>(candidate - reference.begin());
      const double dt = std::abs(candidate->time_s - t);
      if (dt <= best_dt && !used[r]) {
        best = r;
        best_dt = dt;
      }
    }
    if (best == reference.size()) continue;
    used[best] = 1;
    pairs.emplace_back(best, e);
  }
  return pairs;
}

}  // namespace

ApeResult absolute_pose_error(const std::vector<StampedPose>& reference, const std::vector<StampedPose>& estimate,
                              const ApeOptions& options) {
  const auto pairs = associate(reference, estimate, options);
  if (pairs.size() < 3) {
    throw InputError("ape: only " + std::to_string(pairs.size()) + " poses associate within " +
                     std::to_string(options.max_time_difference_s) +
                     " s (need 3); check the time offset and that both files cover the same time");
  }
  Eigen::Matrix3Xd ref(3, static_cast<Eigen::Index>(pairs.size())), est(3, static_cast<Eigen::Index>(pairs.size()));
  ApeResult result;
  for (size_t k = 0; k < pairs.size(); ++k) {
    ref.col(static_cast<Eigen::Index>(k)) = reference[pairs[k].first].pose.translation;
    est.col(static_cast<Eigen::Index>(k)) = estimate[pairs[k].second].pose.translation;
    result.times_s.push_back(reference[pairs[k].first].time_s);
  }
  result.pairs = pairs.size();
  if (options.alignment != Alignment::kNone) {
    // Umeyama (1991), as evo's align_trajectory: least-squares similarity from estimate to reference.
    const Eigen::Matrix4d t = Eigen::umeyama(est, ref, options.alignment == Alignment::kSim3);
    if (!t.allFinite()) throw InputError("ape: the alignment is degenerate (are the positions all on a line?)");
    const Eigen::Matrix3d scaled = t.topLeftCorner<3, 3>();
    result.scale = options.alignment == Alignment::kSim3 ? std::cbrt(scaled.determinant()) : 1.0;
    result.alignment.rotation = Eigen::Quaterniond(scaled / result.scale).normalized();
    result.alignment.translation = t.topRightCorner<3, 1>();
    est = (scaled * est).colwise() + result.alignment.translation;
  }
  for (Eigen::Index k = 0; k < ref.cols(); ++k) result.errors_m.push_back((ref.col(k) - est.col(k)).norm());
  std::vector<double> sorted = result.errors_m;
  std::sort(sorted.begin(), sorted.end());
  const auto n = static_cast<double>(sorted.size());
  double sum = 0.0, sum2 = 0.0;
  for (const double e : sorted) {
    sum += e;
    sum2 += e * e;
  }
  result.mean_m = sum / n;
  result.rmse_m = std::sqrt(sum2 / n);
  result.std_m = std::sqrt(std::max(sum2 / n - result.mean_m * result.mean_m, 0.0));  // evo: numpy std (ddof 0)
  const size_t mid = sorted.size() / 2;
  result.median_m = sorted.size() % 2 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  result.min_m = sorted.front();
  result.max_m = sorted.back();
  return result;
}

}  // namespace lidartwin
