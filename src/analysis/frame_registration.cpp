// Registering a moving sensor's frames to each other: one trajectory of knots at the frames'
// starts, solved together by Gauss-Newton on point-to-plane residuals between neighbouring frames.
#include "lidartwin/analysis/frame_registration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <fmt/format.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "analysis/capture_points.h"
#include "lidartwin/error.h"

namespace lidartwin {
namespace {

using analysis_detail::BeamProjector;
using analysis_detail::FramePoints;

constexpr int kBlock = 6;  // a knot's perturbation: rotation (world axes), then translation
// The robust scale never falls below this: a narrower Cauchy weight left the knots of frames
// still a few centimetres off where their points disagree, and stalled there (measured).
constexpr double kMinScale = 0.05;
constexpr double kMinGap = 0.1;  // the association limit's floor beyond the beam spacing, m

// The unit normal of the surface around pixel i of a frame, in its sensor frame, from its
// neighbours in the frame's grid (principal axes); none where they do not make a surface (an
// edge, a pole, scatter) or are too few.
std::optional<Eigen::Vector3f> normal_at(const FramePoints& frame, const BeamProjector& projector, int reach,
                                         size_t i) {
  const int m = static_cast<int>(i / static_cast<size_t>(frame.height));
  const int r = static_cast<int>(i % static_cast<size_t>(frame.height));
  const Eigen::Vector3f& centre = frame.sensor[i];
  const float radius = 0.05f + 0.08f * frame.range_m[i];  // a few beam spacings at any range
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  Eigen::Matrix3f outer = Eigen::Matrix3f::Zero();
  int n = 0;
  for (int dm = -reach; dm <= reach; ++dm) {
    for (int dr = -2; dr <= 2; ++dr) {
      const std::optional<BeamProjector::Pixel> near = projector.beside(m, r, dm, dr);
      if (!near) continue;
      const size_t j = frame.index(near->m, near->r);
      if (!frame.returned(j)) continue;
      const Eigen::Vector3f d = frame.sensor[j] - centre;
      if (d.squaredNorm() > radius * radius) continue;
      sum += d;
      outer += d * d.transpose();
      ++n;
    }
  }
  if (n < 6) return std::nullopt;
  const Eigen::Vector3f mean = sum / static_cast<float>(n);
  const Eigen::Matrix3f covariance = outer / static_cast<float>(n) - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eigen;
  eigen.computeDirect(covariance);
  const Eigen::Vector3f values = eigen.eigenvalues();  // ascending
  if (!(values(1) > 0.0f) || values(0) > 0.2f * values(1) || values(1) < 0.05f * values(2)) return std::nullopt;
  Eigen::Vector3f normal = eigen.eigenvectors().col(0).normalized();
  if (normal.dot(centre) > 0.0f) normal = -normal;  // facing the sensor
  return normal;
}

// What one source frame adds to the normal equations: its residuals involve the knots k - 1 ..
// k + 2 only (its own two and its neighbours' two), summed here and added to the whole system in
// frame order, so the result does not depend on the threads.
struct FrameSums {
  static constexpr int kKnots = 4;
  Eigen::Matrix<double, kKnots * kBlock, kKnots* kBlock> h = decltype(h)::Zero();
  Eigen::Matrix<double, kKnots * kBlock, 1> g = decltype(g)::Zero();
  std::vector<double> residuals;
  double weighted2 = 0.0, weights = 0.0;
};

// Where column time t lies between the knots: knot k and the weight of knot k + 1.
struct KnotWeight {
  size_t k = 0;
  double u = 0.0;
};
KnotWeight knot_weight(const std::vector<double>& times, double t) {
  auto it = std::upper_bound(times.begin(), times.end(), t);
  size_t k = it == times.begin() ? 0 : static_cast<size_t>(it - times.begin()) - 1;
  k = std::min(k, times.size() - 2);
  const double u = (t - times[k]) / (times[k + 1] - times[k]);
  return {k, std::clamp(u, 0.0, 1.0)};
}

Eigen::Quaterniond exp_rotation(const Eigen::Vector3d& omega) {
  const double angle = omega.norm();
  if (angle < 1e-15) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle));
}

// Evenly spread pixels of a frame to register: returns within the ranges, every stride-th.
std::vector<size_t> sample_pixels(const FramePoints& f, const RegistrationOptions& options) {
  std::vector<size_t> candidates;
  for (size_t i = 0; i < f.range_m.size(); ++i) {
    const auto range = static_cast<double>(f.range_m[i]);
    if (range >= options.min_range_m && range <= options.max_range_m) candidates.push_back(i);
  }
  const size_t stride = std::max<size_t>(1, candidates.size() / std::max<size_t>(options.points_per_frame, 1));
  std::vector<size_t> out;
  for (size_t k = 0; k < candidates.size(); k += stride) out.push_back(candidates[k]);
  return out;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

FrameRegistration register_frames(const MeasuredCapture& capture, WorkerPool& pool,
                                  const RegistrationOptions& options) {
  std::vector<FramePoints> frames = analysis_detail::capture_points(capture);
  const size_t n_frames = frames.size();
  if (n_frames < 2) {
    throw InputError(fmt::format("--map: the capture has {} frame{}; registering a moving sensor needs at least 2",
                                 n_frames, n_frames == 1 ? "" : "s"));
  }
  const BeamProjector projector(capture.metadata);
  const double period = 1.0 / static_cast<double>(capture.metadata.format.fps);
  std::vector<double> times;
  for (size_t k = 0; k < n_frames; ++k) {
    if (!std::isfinite(frames[k].start_s)) {
      throw InputError(fmt::format("--map: frame {} of the capture has no valid column", k));
    }
    if (k > 0 && frames[k].start_s <= times.back()) {
      throw InputError(fmt::format("--map: frame {} starts at {:.6f} s, not after frame {} ({:.6f} s)", k,
                                   frames[k].start_s, k - 1, times.back()));
    }
    times.push_back(frames[k].start_s);
  }
  times.push_back(std::max(frames.back().start_s + period, frames.back().end_s + 1e-6));
  std::vector<Pose> knots(n_frames + 1);

  const int column_reach =
      std::max(1, static_cast<int>(std::lround(projector.row_spacing_rad() / projector.column_spacing_rad())));
  std::vector<std::vector<size_t>> samples;
  for (const FramePoints& f : frames) samples.push_back(sample_pixels(f, options));
  // Every return's normal, once: in the sensor frame they do not change as the knots move.
  std::vector<std::vector<std::optional<Eigen::Vector3f>>> normals(n_frames);
  pool.run(static_cast<int>(n_frames), [&](int, int item) {
    const FramePoints& f = frames[static_cast<size_t>(item)];
    auto& out = normals[static_cast<size_t>(item)];
    out.assign(f.sensor.size(), std::nullopt);
    for (size_t i = 0; i < f.sensor.size(); ++i) {
      if (f.returned(i)) out[i] = normal_at(f, projector, 2 * column_reach, i);
    }
  });
  size_t returns = 0;
  for (const auto& s : samples) returns += s.size();
  if (returns < 100 * n_frames) {
    throw InputError(fmt::format("--map: only {} returns between {} and {} m in {} frames; too few to register",
                                 returns, options.min_range_m, options.max_range_m, n_frames));
  }
  const double spacing = std::max(projector.row_spacing_rad(), projector.column_spacing_rad());
  const size_t unknowns = static_cast<size_t>(kBlock) * n_frames;  // knots 1..N; knot 0 is the world
  FrameRegistration out;
  // Start wide (frames a quarter of a metre apart associate with the wrong points at first) and
  // narrow as the knots settle.
  double scale = 0.3;    // robust scale of the point-to-plane distances
  double max_gap = 2.0;  // point-to-point association limit beyond the beam spacing
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    std::vector<StampedPose> stamped;
    for (size_t k = 0; k <= n_frames; ++k) stamped.push_back({times[k], knots[k]});
    const Trajectory trajectory(stamped, false);
    const TrajectoryPoses placed(trajectory);
    pool.run(static_cast<int>(n_frames),
             [&](int, int item) { analysis_detail::place(frames[static_cast<size_t>(item)], placed); });

    std::vector<FrameSums> sums(n_frames);
    pool.run(static_cast<int>(n_frames), [&](int, int item) {
      const auto k = static_cast<size_t>(item);
      FrameSums& sum = sums[k];
      const FramePoints& source = frames[k];
      for (const size_t j : {k - 1, k + 1}) {
        if (j >= n_frames) continue;  // k - 1 wraps for k = 0
        const FramePoints& target = frames[j];
        for (const size_t s : samples[k]) {
          const Eigen::Vector3f x = source.world[s];
          const auto range = static_cast<double>(source.range_m[s]);
          const BeamProjector::Pixel seed = projector.project_world(target, x);
          const float gap = static_cast<float>(max_gap + 3.0 * range * spacing);
          float best = gap * gap;
          size_t best_i = std::numeric_limits<size_t>::max();
          for (int dm = -2 * column_reach; dm <= 2 * column_reach; ++dm) {
            for (int dr = -2; dr <= 2; ++dr) {
              const std::optional<BeamProjector::Pixel> near = projector.beside(seed.m, seed.r, dm, dr);
              if (!near) continue;
              const size_t t = target.index(near->m, near->r);
              if (!target.returned(t)) continue;
              const float d2 = (target.world[t] - x).squaredNorm();
              if (d2 < best) {
                best = d2;
                best_i = t;
              }
            }
          }
          if (best_i == std::numeric_limits<size_t>::max()) continue;
          const std::optional<Eigen::Vector3f>& local = normals[j][best_i];
          if (!local) continue;
          const auto tm = static_cast<size_t>(best_i / static_cast<size_t>(target.height));
          const Eigen::Vector3d n = (target.rotation[tm] * *local).cast<double>();
          const Eigen::Vector3d xs = x.cast<double>(), xt = target.world[best_i].cast<double>();
          const double e = n.dot(xs - xt);
          sum.residuals.push_back(std::abs(e));
          const double w = 1.0 / (1.0 + (e / (2.0 * scale)) * (e / (2.0 * scale)));  // Cauchy
          sum.weighted2 += w * e * e;
          sum.weights += w;
          // d e / d knot: the point moves with its column, a blend of the knots around its time.
          const auto sm = static_cast<size_t>(s / static_cast<size_t>(source.height));
          const KnotWeight ks = knot_weight(times, source.column_time_s[sm]);
          const KnotWeight kt = knot_weight(times, target.column_time_s[tm]);
          Eigen::Matrix<double, kBlock, 1> js, jt;
          js << xs.cross(n), n;
          jt << -xt.cross(n), -n;
          const std::array<std::pair<size_t, Eigen::Matrix<double, kBlock, 1>>, 4> terms{{
              {ks.k, (1.0 - ks.u) * js},
              {ks.k + 1, ks.u * js},
              {kt.k, (1.0 - kt.u) * jt},
              {kt.k + 1, kt.u * jt},
          }};
          const auto in_block = [k](size_t knot) { return knot + 1 >= k && knot + 1 - k < 4; };  // k - 1 .. k + 2
          for (const auto& [a, ja] : terms) {
            if (!in_block(a)) continue;
            const auto ra = static_cast<Eigen::Index>((a + 1 - k) * kBlock);  // knot k - 1 is local 0
            sum.g.segment<kBlock>(ra) += w * e * ja;
            for (const auto& [b, jb] : terms) {
              if (!in_block(b)) continue;
              const auto rb = static_cast<Eigen::Index>((b + 1 - k) * kBlock);
              sum.h.block<kBlock, kBlock>(ra, rb) += w * ja * jb.transpose();
            }
          }
        }
      }
    });
    Eigen::MatrixXd h = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(unknowns), static_cast<Eigen::Index>(unknowns));
    Eigen::VectorXd g = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(unknowns));
    std::vector<double> residuals;
    double weighted2 = 0.0, weights = 0.0;
    for (size_t k = 0; k < n_frames; ++k) {
      const FrameSums& sum = sums[k];
      residuals.insert(residuals.end(), sum.residuals.begin(), sum.residuals.end());
      weighted2 += sum.weighted2;
      weights += sum.weights;
      for (int la = 0; la < FrameSums::kKnots; ++la) {
        const size_t a = k + static_cast<size_t>(la) - 1;  // knot; knot 0 is the world, fixed
        if (k + static_cast<size_t>(la) < 2 || a > n_frames) continue;
        const auto ra = static_cast<Eigen::Index>((a - 1) * kBlock);
        g.segment<kBlock>(ra) += sum.g.segment<kBlock>(la * kBlock);
        for (int lb = 0; lb < FrameSums::kKnots; ++lb) {
          const size_t b = k + static_cast<size_t>(lb) - 1;
          if (k + static_cast<size_t>(lb) < 2 || b > n_frames) continue;
          h.block<kBlock, kBlock>(ra, static_cast<Eigen::Index>((b - 1) * kBlock)) +=
              sum.h.block<kBlock, kBlock>(la * kBlock, lb * kBlock);
        }
      }
    }
    if (residuals.size() < 6 * n_frames) {
      throw InputError(fmt::format(
          "--map: only {} point pairs between neighbouring frames; the frames do not overlap (is the sensor "
          "moving faster than a few metres per frame, or are the returns too sparse?)",
          residuals.size()));
    }
    // Levenberg damping keeps directions the scene does not constrain (a corridor's length) still.
    for (Eigen::Index i = 0; i < h.rows(); ++i) h(i, i) += 1e-6 * h(i, i) + 1e-9;
    const Eigen::VectorXd delta = -h.ldlt().solve(g);
    double largest = 0.0;
    for (size_t k = 1; k <= n_frames; ++k) {
      const Eigen::Matrix<double, kBlock, 1> d = delta.segment<kBlock>(static_cast<Eigen::Index>((k - 1) * kBlock));
      const Eigen::Quaterniond q = exp_rotation(d.head<3>());
      knots[k].rotation = (q * knots[k].rotation).normalized();
      knots[k].translation = q * knots[k].translation + d.tail<3>();
      largest = std::max({largest, d.head<3>().norm() * 10.0, d.tail<3>().norm()});  // 0.1 mrad ~ 1 mm at 10 m
    }
    const bool narrowest = max_gap <= kMinGap;  // this iteration associated at the floor
    scale = std::max(std::min(scale, 1.4826 * median_of(residuals)), kMinScale);
    max_gap = std::max(kMinGap, 0.7 * max_gap);
    out.pairs = residuals.size();
    out.rms_m = weights > 0.0 ? std::sqrt(weighted2 / weights) : 0.0;
    out.iterations = iteration + 1;
    // Converged when no knot moves a tenth of a millimetre (10 m away, for a turn), or half a
    // millimetre once the association limit is at its floor: well below what the pairs determine.
    // There the last steps do not fall to nothing: points trading partners kept them at 0.1-0.2 mm
    // on a 50-frame drive, which ran registration to its 30 iterations (11 s of compare_bench's 34).
    if ((iteration >= 4 && largest < 1e-4) || (narrowest && largest < 5e-4)) break;
  }
  std::vector<StampedPose> stamped;
  for (size_t k = 0; k <= n_frames; ++k) {
    stamped.push_back({times[k], knots[k]});
    if (k > 0) out.path_length_m += (knots[k].translation - knots[k - 1].translation).norm();
  }
  out.trajectory = Trajectory(stamped, false);
  return out;
}

}  // namespace lidartwin
