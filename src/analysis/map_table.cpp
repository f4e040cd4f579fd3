// Map mode's pixel table: each return against a surface fitted to the other frames' points.
#include "lidartwin/analysis/map_table.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>
#include <optional>

#include <fmt/format.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "analysis/capture_points.h"
#include "lidartwin/analysis/pixel_likelihood.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/wire_context.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin {
namespace {

using analysis_detail::BeamProjector;
using analysis_detail::FramePoints;

constexpr size_t kMinPoints = 12;
constexpr size_t kQuadricPoints = 24;  // from this many points the surface may curve
constexpr double kMinPatchM = 0.15;    // half-width of the patch at short range
// The patch's window in pixels either side, at most; a window that wide (returns within about a
// metre, where kMinPatchM spans dozens of pixels) is gathered at every other pixel: its points lie
// millimetres apart, thousands of them (a plant drive's returns under 1 m took half of map mode's
// time), and a quarter of them determines the surface as well.
constexpr int kMaxPatchRows = 24;
constexpr int kMaxPatchColumns = 48;
constexpr double kMaxCosGrazing = 0.0871557;       // cos 85 degrees
constexpr double kMinNormalAgreement = 0.9063078;  // cos 25 degrees
constexpr double kMaxRowStepM = 1.0;               // within a frame: its scan lines' spacing on a surface
// The incidence's strip along the beam (strip_cos_incidence): its reach either side in spacings of
// the beams' crossings, at most kMaxStripM, and its plane's Gauss-Newton steps from the patch's.
constexpr double kStripSpacings = 2.5;
constexpr double kMaxStripM = 3.0;
constexpr int kStripSteps = 1;

enum class Verdict { kCompared, kEdge, kUnsupported, kNotSurface, kOffSurface, kGrazing };

// Where a pixel's beam crosses the surface the other frames saw.
struct Crossing {
  float range_m = 0.0f;
  float cos_incidence = 1.0f;
  float variance_m2 = 0.0f;  // of the reference range along the beam
};

// The points a reference surface is fitted to, each with its beam's direction (world frame, unit):
// a point errs along its own beam.
struct Patch {
  std::vector<Eigen::Vector3d> points, beams;
  void clear() {
    points.clear();
    beams.clear();
  }
  size_t size() const { return points.size(); }
};

// A pixel beside a depth step in its own frame (0.15 m or 3 %, finer than the scene table's 0.3 m
// or 5 %: a reference patch straddling a smaller step still mixes two surfaces):
// along its row, a neighbour's range differs by a step; along its column, the range bends by one
// (the second difference: the ground seen at grazing incidence changes range fast from row to row
// but evenly).
bool beside_step(const FramePoints& f, const BeamProjector& projector, int m, int r, int column_reach) {
  const float range = f.range_m[f.index(m, r)];
  const auto step = [](float a, float b) { return std::abs(a - b) > std::max(0.15f, 0.03f * std::max(a, b)); };
  const auto range_at = [&](int dm, int dr) {
    const std::optional<BeamProjector::Pixel> p = projector.beside(m, r, dm, dr);
    return p ? f.range_m[f.index(p->m, p->r)] : 0.0f;
  };
  for (int dm = -column_reach; dm <= column_reach; ++dm) {
    if (dm == 0) continue;
    const float other = range_at(dm, 0);
    if (other == 0.0f || step(other, range)) return true;
  }
  const float up = range_at(0, -1), down = range_at(0, 1);
  if ((up == 0.0f) != (down == 0.0f)) return true;  // the rim of a surface against the sky
  return up > 0.0f && down > 0.0f && step(0.5f * (up + down), range);
}

// The robust spread of deviations about a surface: 1.4826 times their (upper) median, a Gaussian's
// sigma. Runs once or twice per pixel: the copy it sorts is kept by each worker thread.
double robust_spread(const std::vector<double>& deviations) {
  thread_local std::vector<double> sorted;
  sorted = deviations;
  const auto mid = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
  std::nth_element(sorted.begin(), mid, sorted.end());
  return 1.4826 * *mid;
}

// Two doubles in one vector register (GCC's and Clang's vector extension: SSE2, NEON): the fits'
// terms are built and summed in pairs. Each lane's arithmetic is the scalar's.
using Pair = double __attribute__((vector_size(16)));

// A surface's six basis terms (Surface::basis) in three pairs.
struct Terms {
  Pair pair[3];
  static Terms basis(double u, double v) { return {{Pair{1.0, u}, Pair{v, u * u}, Pair{u * v, v * v}}}; }
  Terms over(double scale) const {
    const Pair s = {scale, scale};
    return {{pair[0] / s, pair[1] / s, pair[2] / s}};
  }
  double operator[](int i) const { return pair[i / 2][i % 2]; }
};

// The surface through points, in the frame of their principal axes: w = c . basis(u, v), a plane
// or, with enough points, a quadric (curved tanks and pipes are no planes at a patch's scale).
struct Surface {
  Eigen::Vector3d centre, e_u, e_v, e_w;
  int terms = 3;
  Eigen::Matrix<double, 6, 1> c = Eigen::Matrix<double, 6, 1>::Zero();
  double residual_variance = 0.0;  // in height
  double robust_height = 0.0;      // the points' robust spread off the surface (fit), in height
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();  // of c (fit_along_beams)
  static Eigen::Matrix<double, 6, 1> basis(double u, double v) {
    Eigen::Matrix<double, 6, 1> b;
    b << 1.0, u, v, u * u, u * v, v * v;
    return b;
  }
  // c . basis(u, v), the terms written out: built as a vector on the stack and read back, the basis
  // cost a store-forwarding stall per point (the same products, summed in the same order).
  double height(double u, double v) const {
    double sum = 0.0;
    sum += c(0) * 1.0;
    sum += c(1) * u;
    sum += c(2) * v;
    if (terms == 6) {
      sum += c(3) * (u * u);
      sum += c(4) * (u * v);
      sum += c(5) * (v * v);
    }
    return sum;
  }
  Eigen::Vector2d slope(double u, double v) const {
    Eigen::Vector2d s(c(1), c(2));
    if (terms == 6) s += Eigen::Vector2d(2.0 * c(3) * u + c(4) * v, c(4) * u + 2.0 * c(5) * v);
    return s;
  }
  // How much height a line of direction d (surface frame) gains per metre across the surface at
  // (u, v): a beam's range error is a height error over this.
  double rise(double u, double v, const Eigen::Vector3d& d) const {
    const Eigen::Vector2d g = slope(u, v);
    return d.z() - g.x() * d.x() - g.y() * d.y();
  }
  // The variance of the height at (u, v) that the coefficients' errors make.
  double height_variance(double u, double v) const {
    const Eigen::Matrix<double, 6, 1> b = basis(u, v);
    double sum = 0.0;
    for (int i = 0; i < terms; ++i) {
      for (int j = 0; j < terms; ++j) sum += b(i) * covariance(i, j) * b(j);
    }
    return sum;
  }
};

class MapReferences {
 public:
  MapReferences(const std::vector<FramePoints>& frames, const BeamProjector& projector, int neighbour_frames,
                bool within_frame)
      : frames_(frames), projector_(projector), neighbour_frames_(neighbour_frames), within_frame_(within_frame) {
    column_reach_ =
        std::max(1, static_cast<int>(std::lround(projector.row_spacing_rad() / projector.column_spacing_rad())));
  }

  // The range of pixel (m, r) as its row sees it: the median of its beam's returns in the two
  // columns either side (a surface's range changes evenly along a row, and a depth step there
  // leaves the pixel out: beside_step), or its own where fewer than two returned.
  double row_range(const FramePoints& f, int m, int r) const {
    std::array<float, 4> near;
    near.fill(std::numeric_limits<float>::infinity());  // sorted after the returns
    size_t n = 0;
    for (const int dm : {-2, -1, 1, 2}) {
      const std::optional<BeamProjector::Pixel> p = projector_.beside(m, r, dm, 0);
      if (p && f.returned(f.index(p->m, p->r))) near[n++] = f.range_m[f.index(p->m, p->r)];
    }
    if (n < 2) return static_cast<double>(f.range_m[f.index(m, r)]);
    std::sort(near.begin(), near.end());
    return 0.5 * (static_cast<double>(near[(n - 1) / 2]) + static_cast<double>(near[n / 2]));
  }

  Verdict reference(size_t k, int m, int r, Crossing& out, Patch& points) const {
    const FramePoints& own = frames_[k];
    if (beside_step(own, projector_, m, r, column_reach_)) return Verdict::kEdge;
    // Within a frame a pixel's reference is made of its neighbours, and mixed pixels (E6) near an
    // edge are mixed alike: a neighbour beside a step leaves the pixel out too (with one pixel's
    // margin, on the yard drive a fence's returns took references 0.2 m off that followed
    // their own error, correlation +0.3).
    if (within_frame_) {
      for (const auto& [dm, dr] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
        const std::optional<BeamProjector::Pixel> p = projector_.beside(m, r, dm, dr);
        if (p && own.returned(own.index(p->m, p->r)) && beside_step(own, projector_, p->m, p->r, column_reach_)) {
          return Verdict::kEdge;
        }
      }
    }
    const size_t i = own.index(m, r);
    const double range = static_cast<double>(own.range_m[i]);
    // The first patch is gathered around the return's point as its row saw it, not as it measured
    // it: gathered around its own noisy point, which other frames' points a patch took in, and so
    // whether it was judged smooth and how wide it grew, depended on the return's noise and theirs
    // together, and the returns compared kept references that followed their own error (on the
    // independent generator's darkest walls, approached head-on: correlation +0.15 and +0.21, the
    // spread 0.953 of the scene's; centred by the row: +0.01, 0.993).
    const double centre = row_range(own, m, r);
    const Eigen::Vector3f beam_origin =
        own.rotation[static_cast<size_t>(m)] * projector_.origin(m, r) + own.translation[static_cast<size_t>(m)];
    const Eigen::Vector3f beam_direction = own.rotation[static_cast<size_t>(m)] * projector_.direction(m, r);
    const Eigen::Vector3f x = beam_origin + static_cast<float>(centre) * beam_direction;
    const double spacing = std::max(projector_.row_spacing_rad(), projector_.column_spacing_rad());
    // A noisy surface needs a wider patch to show its shape above its roughness: the patch grows
    // (twice, four times) until it does, so that the pixels left out are not the noisiest ones.
    const double base = std::max(kMinPatchM, 1.5 * centre * spacing);
    Surface s;
    double half = base;
    int rows = 1, columns = 1;
    for (int grow = 0;; ++grow) {
      half = base * static_cast<double>(1 << grow);
      rows = std::clamp(static_cast<int>(std::ceil(half / (centre * projector_.row_spacing_rad()))), 1, kMaxPatchRows);
      columns = std::clamp(static_cast<int>(std::ceil(half / (centre * projector_.column_spacing_rad()))), 1,
                           kMaxPatchColumns);
      const size_t frames_used = gather(k, i, x, 1.5 * half, rows, columns, points);
      // One frame's returns are sparser than several frames': the patch grows until it holds enough
      // points for a quadric (a plane through a curved surface's points lies behind its bulge at the
      // patch's centre: tanks at 13-35 m read 12-22 mm long).
      if (within_frame_ && points.size() < kQuadricPoints && grow < 2) continue;
      if (points.size() < kMinPoints || frames_used < (within_frame_ ? 1u : 2u)) return Verdict::kUnsupported;
      const Fit fitted = fit(points, s);
      if (fitted == Fit::kSurface) break;
      if (fitted == Fit::kNotOneSurface || grow == 2) return Verdict::kNotSurface;
    }
    const Eigen::Vector3d origin = beam_origin.cast<double>();
    const Eigen::Vector3d direction = beam_direction.cast<double>();
    double t = range, u = 0.0, v = 0.0;
    if (!cross(s, origin, direction, t, u, v)) return Verdict::kGrazing;
    // The patch again, around where the beam met that surface rather than around the pixel's own
    // point, its points kept by where their beams meet the surface, and refitted along the beams
    // (select_by_beams, fit_along_beams). It is gathered wider than it is kept, by three of the
    // points' spreads along the surface (their spread across it x tan theta): a point errs along its
    // beam, so away from normal incidence partly along the surface, and gathered by its measured
    // position within the radius kept, a point at the rim would be in or out by its own noise (the
    // far rim keeping the points that fell short, the near rim those that overshot, which tilts the
    // surface towards the sensor and makes the incidence, and E4's spread from it, too small).
    const Eigen::Vector3d first_crossing(u, v, s.height(u, v));
    const double kept_radius = 1.5 * half;
    const double cos_first = std::clamp(std::abs(s.rise(u, v, local_direction(s, direction))), kMaxCosGrazing, 1.0);
    const double along_surface = s.robust_height * std::sqrt(1.0 - cos_first * cos_first) / cos_first;
    const double gather_radius = std::min(kept_radius + 3.0 * along_surface, 2.0 * kept_radius);
    const double widen = gather_radius / kept_radius;
    gather(k, i, (origin + t * direction).cast<float>(), gather_radius, static_cast<int>(std::ceil(widen * rows)),
           static_cast<int>(std::ceil(widen * columns)), points);
    if (!select_by_beams(points, s, first_crossing, kept_radius)) return Verdict::kUnsupported;
    if (!fit_along_beams(s)) return Verdict::kNotSurface;
    if (!cross(s, origin, direction, t, u, v)) return Verdict::kGrazing;
    const Eigen::Vector3d d = local_direction(s, direction);
    const Eigen::Vector2d slope = s.slope(u, v);
    const double along_beam = s.rise(u, v, d);  // height per metre of range
    const Eigen::Vector3d normal = Eigen::Vector3d(-slope.x(), -slope.y(), 1.0).normalized();
    // The pixel's own frame must see the same surface: a thin thing seen edge-on (a railing, a
    // beam's flange) lies in front of the larger surface the other frames' points describe.
    if (const std::optional<Eigen::Vector3d> own_normal = own_frame_normal(own, m, r, half)) {
      const Eigen::Vector3d local(s.e_u.dot(*own_normal), s.e_v.dot(*own_normal), s.e_w.dot(*own_normal));
      if (std::abs(local.dot(normal)) < kMinNormalAgreement) return Verdict::kNotSurface;
    }
    double cos_incidence = std::abs(normal.dot(d));
    if (const std::optional<double> strip =
            strip_cos_incidence(k, m, r, s, u, v, d, cos_incidence, range, kept_radius, points)) {
      cos_incidence = *strip;
    }
    if (cos_incidence < kMaxCosGrazing) return Verdict::kGrazing;
    // Within a frame, a surface across the scan lines is known only from the lines beside the
    // pixel's own. Both must have returned: at the frame's top or bottom row, or at a surface's rim,
    // the patch lies on one side of the pixel and its surface is extrapolated there. And they may lie
    // at most kMaxRowStepM apart on it: farther (the ground beyond 80 degrees at 13-20 m), a patch
    // wide enough to hold them spans the ground's unevenness too (on the yard's ground there: the
    // spread 1.2 times the scene's).
    if (within_frame_) {
      const std::optional<double> step = scan_line_step(own, m, r);
      if (!step) return Verdict::kUnsupported;
      if (*step > kMaxRowStepM) return Verdict::kGrazing;
    }
    if (!(t > 0.0) || std::abs(t - range) > std::max(1.0, 0.1 * range)) return Verdict::kOffSurface;
    out.range_m = static_cast<float>(t);
    out.cos_incidence = static_cast<float>(cos_incidence);
    // The surface's error at the crossing, in height, becomes a range error divided by the height
    // the beam gains per metre.
    out.variance_m2 = static_cast<float>(s.height_variance(u, v) / (along_beam * along_beam));
    return Verdict::kCompared;
  }

 private:
  enum class Fit { kSurface, kRough, kNotOneSurface };

  // Where a beam (world frame) meets the surface: its range t (Newton from `t`, the measured range)
  // and the crossing's (u, v) in the surface's frame; false where the beam runs along it.
  static bool cross(const Surface& s, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double& t,
                    double& u, double& v) {
    const Eigen::Vector3d o(s.e_u.dot(origin - s.centre), s.e_v.dot(origin - s.centre), s.e_w.dot(origin - s.centre));
    const Eigen::Vector3d d = local_direction(s, direction);
    if (std::abs(d.z()) < kMaxCosGrazing) return false;
    for (int step = 0; step < 4; ++step) {
      u = o.x() + t * d.x();
      v = o.y() + t * d.y();
      const double gap = o.z() + t * d.z() - s.height(u, v);
      const double derivative = s.rise(u, v, d);
      if (std::abs(derivative) < 1e-6) return false;
      t -= gap / derivative;
    }
    u = o.x() + t * d.x();
    v = o.y() + t * d.y();
    return true;
  }

  static Eigen::Vector3d local_direction(const Surface& s, const Eigen::Vector3d& direction) {
    return {s.e_u.dot(direction), s.e_v.dot(direction), s.e_w.dot(direction)};
  }

  // The patch's points and beams in the surface's frame (local_, beams_).
  static void to_local(const Patch& patch, const Surface& s) {
    local_.clear();
    beams_.clear();
    for (size_t j = 0; j < patch.size(); ++j) {
      const Eigen::Vector3d q = patch.points[j] - s.centre;
      const Eigen::Vector3d& b = patch.beams[j];
      local_.emplace_back(s.e_u.dot(q), s.e_v.dot(q), s.e_w.dot(q));
      beams_.emplace_back(s.e_u.dot(b), s.e_v.dot(b), s.e_w.dot(b));
    }
  }

  // Which points a patch holds decides its shape where they sit at its rim: taken within a radius
  // of the pixel's measured point, a point of another frame is in or out by its own noise (along
  // its beam: across the ground at grazing incidence), and the patch is centred by the pixel's own
  // noise. Both then pass into the reference: on the ground at 80-85 degrees (plant drive, E4
  // hidden), the reference moved by a third of the pixel's own error (correlation +0.35 with a fit
  // along the beams). So the points kept are those whose beams meet the first surface within
  // `radius` of where the pixel's beam meets it, gathered around that crossing: positions free of
  // every point's noise (correlation +0.05), and within five robust deviations in height of it
  // (the gather is wider than `radius`: a second surface's points whose beams pass the crossing,
  // a box's face before the ground, stay out). False when fewer than kMinPoints remain.
  //
  // The height cut's scale: the patch's robust spread (kPatch), or for the incidence's strip the
  // strip's own points' robust spread about the plane, at least the patch's (kStrip). The strip
  // starts from the patch's tangent plane, whose slope along the beam is what it is there to
  // correct: beside the sensor's path, where the frames' scan lines fall on one another, a patch
  // holds one or two lines and its plane may lean by degrees, 10 cm over the strip's 2 m, and the
  // patch's spread (a centimetre or two) then cut the strip's far end away and left the rest
  // agreeing with the patch's lean.
  enum class HeightCut { kPatch, kStrip };
  static bool select_by_beams(const Patch& patch, Surface& s, const Eigen::Vector3d& crossing, double radius,
                              HeightCut cut = HeightCut::kPatch) {
    to_local(patch, s);
    thread_local std::vector<double> heights;  // kStrip: of the points kept so far, off the surface
    heights.clear();
    size_t kept = 0;
    for (size_t j = 0; j < local_.size(); ++j) {
      const Eigen::Vector3d& q = local_[j];
      const Eigen::Vector3d& d = beams_[j];
      const double per_metre = s.rise(q.x(), q.y(), d);
      if (std::abs(per_metre) < kMaxCosGrazing) continue;
      const double above = q.z() - s.height(q.x(), q.y());  // the surface's quadric, once a point
      const Eigen::Vector3d on_surface = q - (above / per_metre) * d;
      if ((on_surface - crossing).squaredNorm() > radius * radius) continue;
      const double off = std::abs(above);
      if (cut == HeightCut::kPatch && off > 5.0 * s.robust_height) continue;  // another surface
      local_[kept] = q;
      beams_[kept] = d;
      if (cut == HeightCut::kStrip) heights.push_back(off);
      ++kept;
    }
    if (cut == HeightCut::kStrip && kept > 0) {
      const double limit = 5.0 * std::max(robust_spread(heights), s.robust_height);
      size_t near = 0;
      for (size_t j = 0; j < kept; ++j) {
        if (heights[j] > limit) continue;  // another surface
        local_[near] = local_[j];
        beams_[near] = beams_[j];
        ++near;
      }
      kept = near;
    }
    local_.resize(kept);
    beams_.resize(kept);
    if (kept < kMinPoints) return false;
    if (kept < kQuadricPoints) s.terms = 3;
    return true;
  }

  static inline thread_local std::vector<Eigen::Vector3d> local_, beams_;

  // The least-squares solution of the first P basis terms' normal equations and, when asked, the
  // inverse of their matrix, with fixed-size matrices (no allocation per pixel); false when the
  // points do not determine them.
  template <int P>
  static bool solve_normal_equations(const Eigen::Matrix<double, 6, 6>& normal, const Eigen::Matrix<double, 6, 1>& rhs,
                                     Eigen::Matrix<double, 6, 1>& solution,
                                     Eigen::Matrix<double, 6, 6>* inverse = nullptr) {
    const Eigen::LDLT<Eigen::Matrix<double, P, P>> ldlt(normal.template topLeftCorner<P, P>());
    if (ldlt.info() != Eigen::Success || ldlt.rcond() < 1e-12) return false;
    solution.setZero();
    solution.template head<P>() = ldlt.solve(rhs.template head<P>());
    if (inverse) {
      inverse->setZero();
      inverse->template topLeftCorner<P, P>() = ldlt.solve(Eigen::Matrix<double, P, P>::Identity());
    }
    return true;
  }

  // The sums of a least-squares fit in the first P basis terms, point by point: of b b^T (or w b b^T)
  // and of b z, in pairs of lanes (Terms) held in registers with P known at compile time. The
  // normal equations' LDLT reads the lower triangle (symmetric() fills the rest where the whole
  // matrix is needed). Each element is the same product, summed in the same order, as in the outer
  // product, so the fits keep their bits; a 6x6 matrix updated in memory for every point, or a
  // basis built a double at a time and read back in pairs, stalled on store forwarding at every
  // point (most of map mode's time).
  template <int P>
  struct NormalSums {
    static constexpr int kPairs = (P + 1) / 2;
    Pair sums[P][kPairs] = {};  // [j][q]: column j's rows 2q and 2q + 1
    Pair rhs[kPairs] = {};
    void add(const Terms& b, double z) {
      for (int j = 0; j < P; ++j) {
        const Pair bj = {b[j], b[j]};
        for (int q = 0; q < kPairs; ++q) sums[j][q] += b.pair[q] * bj;
      }
      const Pair zz = {z, z};
      for (int q = 0; q < kPairs; ++q) rhs[q] += b.pair[q] * zz;
    }
    void add_weighted(const Terms& b, double w) {
      const Pair ww = {w, w};
      for (int j = 0; j < P; ++j) {
        const Pair bj = {b[j], b[j]};
        for (int q = 0; q < kPairs; ++q) sums[j][q] += ww * (b.pair[q] * bj);
      }
    }
    Eigen::Matrix<double, 6, 6> matrix() const {
      Eigen::Matrix<double, 6, 6> m = Eigen::Matrix<double, 6, 6>::Zero();
      for (int j = 0; j < P; ++j) {
        for (int i = j; i < P; ++i) m(i, j) = sums[j][i / 2][i % 2];
      }
      return m;
    }
    Eigen::Matrix<double, 6, 1> right() const {
      Eigen::Matrix<double, 6, 1> r = Eigen::Matrix<double, 6, 1>::Zero();
      for (int i = 0; i < P; ++i) r(i) = rhs[i / 2][i % 2];
      return r;
    }
  };
  // The height fit's normal equations of the points (surface frame) in P terms.
  template <int P>
  static bool fit_heights(const std::vector<Eigen::Vector3d>& local, Surface& s) {
    NormalSums<P> sums;
    for (const auto& q : local) sums.add(Terms::basis(q.x(), q.y()), q.z());
    return solve_normal_equations<P>(sums.matrix(), sums.right(), s.c);
  }
  static void symmetric(Eigen::Matrix<double, 6, 6>& m) { m.triangularView<Eigen::StrictlyUpper>() = m.transpose(); }

  static Fit fit(const Patch& patch, Surface& s) {
    const std::vector<Eigen::Vector3d>& points = patch.points;
    const auto n = static_cast<double>(points.size());
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : points) mean += p;
    mean /= n;
    // The six sums in locals (an outer product added to a matrix in memory stalled on its stores).
    double xx = 0.0, xy = 0.0, xz = 0.0, yy = 0.0, yz = 0.0, zz = 0.0;
    for (const auto& p : points) {
      const Eigen::Vector3d d = p - mean;
      xx += d.x() * d.x();
      xy += d.y() * d.x();
      xz += d.z() * d.x();
      yy += d.y() * d.y();
      yz += d.z() * d.y();
      zz += d.z() * d.z();
    }
    Eigen::Matrix3d covariance;
    covariance << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    covariance /= n;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
    const Eigen::Vector3d values = eigen.eigenvalues();  // ascending
    if (!(values(1) > 0.0) || values(1) < 0.05 * values(2))
      return Fit::kNotOneSurface;  // a line of points, not a patch
    s.centre = mean;
    s.e_w = eigen.eigenvectors().col(0);
    s.e_u = eigen.eigenvectors().col(2);
    s.e_v = s.e_w.cross(s.e_u);
    s.terms = points.size() >= kQuadricPoints ? 6 : 3;
    // Scratch kept by each worker thread: this runs once per pixel, a few hundred thousand times.
    thread_local std::vector<Eigen::Vector3d> local;
    thread_local std::vector<double> deviations;
    local.clear();
    for (const auto& p : points) {
      const Eigen::Vector3d q = p - mean;
      local.emplace_back(s.e_u.dot(q), s.e_v.dot(q), s.e_w.dot(q));
    }
    if (s.terms == 6 ? !fit_heights<6>(local, s) : !fit_heights<3>(local, s)) return Fit::kNotOneSurface;
    double rss = 0.0;
    for (const auto& q : local) {
      const double e = q.z() - s.height(q.x(), q.y());
      rss += e * e;
    }
    s.residual_variance = rss / (n - static_cast<double>(s.terms));
    // One surface at the patch's scale: its roughness well below its extent, and no second surface
    // among its points (a pipe before a wall, the floor beyond a box's edge): at most one of them 5
    // robust deviations off it (a Gaussian puts one of 1.7 million there).
    deviations.clear();
    for (const auto& q : local) deviations.push_back(std::abs(q.z() - s.height(q.x(), q.y())));
    const double robust = robust_spread(deviations);
    s.robust_height = robust;
    const auto far = std::count_if(deviations.begin(), deviations.end(), [&](double d) { return d > 5.0 * robust; });
    // A fold (a corner, an edge's two faces) is fitted by a quadric too, badly: the surface may
    // bend over the patch by a fifth of its half-width at most (a radius of curvature of 2.5
    // half-widths; a 3 m tank seen through a 0.15 m patch bends by a fortieth).
    const double half = 2.0 * std::sqrt(values(2));
    const double sag = (std::abs(s.c(3)) + 0.5 * std::abs(s.c(4)) + std::abs(s.c(5))) * half * half;
    if (far >= 2 || sag >= 0.2 * half) return Fit::kNotOneSurface;
    if (s.residual_variance >= values(1) / 9.0) return Fit::kRough;
    return Fit::kSurface;
  }

  // Least squares across the surface (in height) is not how lidar points err: a point's noise is
  // along its own beam, which at grazing incidence moves it mostly along the surface, into the
  // regressors u and v (the ground at 80 degrees: noise in u six times that in height). That tilts
  // the fit and makes its coefficients' variance from the height residuals wrong (on the ground the
  // reference's error was 1.2-2 times what it gave). So the surface is refitted to each point's
  // range residual along its beam (gauss_newton). A plane stands only where curving it does not
  // fit much better: a tank seen through a patch of a dozen points is no plane, and a plane
  // through them lies behind its bulge by centimetres that no variance counts (a likelihood ratio
  // above 6 ln n, about p = 0.001; quadrics need kQuadricPoints, and fitted to fewer points, in the
  // few scan lines that cross the ground far off, they are not determined).
  static bool fit_along_beams(Surface& s) {
    double rss = 0.0;
    if (s.terms == 6) return gauss_newton(s, 6, rss);
    if (!gauss_newton(s, 3, rss)) return false;
    Surface curved = s;
    double curved_rss = 0.0;
    if (!gauss_newton(curved, 6, curved_rss)) return true;
    const auto n = static_cast<double>(local_.size());
    return !(n * std::log(rss / curved_rss) > 6.0 * std::log(n));
  }

  // Gauss-Newton on the points' range residuals along their beams, from the surface's coefficients
  // (its first p terms): the regressors are taken where each point's beam meets the surface, free
  // of its noise. The coefficients' covariance is the sandwich of those residuals (HC1): points
  // farther away, or weaker, with a wider spread count as they err. False when the points do not
  // determine the p terms. With `steps` it takes that many steps and stops, without the covariance
  // (the incidence's strip: one step from the patch's tangent plane; a second moved the plant
  // drive's ground incidence by -0.05 degrees, median, and its spread ratio at 8-13 m from 1.02 to
  // 1.04 of the scene's: the converged fit leans towards the sensor, as the patch's own does by
  // less than its scatter, for a reason not yet found).
  static bool gauss_newton(Surface& s, int p, double& rss, int steps = 0) {
    return p == 6 ? gauss_newton<6>(s, rss, steps) : gauss_newton<3>(s, rss, steps);
  }
  template <int P>
  static bool gauss_newton(Surface& s, double& rss, int steps) {
    const size_t n = local_.size();
    if (n <= static_cast<size_t>(P) + 2) return false;
    s.terms = P;
    thread_local std::vector<Terms> gradients;
    thread_local std::vector<double> residuals;
    gradients.resize(n);
    residuals.resize(n);
    Eigen::Matrix<double, 6, 6> inverse;
    // Plain pointers and a local sum: through the thread-local vectors and `rss` by reference, every
    // point reloaded their addresses and waited on the sum's store.
    const Eigen::Vector3d* points = local_.data();
    const Eigen::Vector3d* beams = beams_.data();
    Terms* gradient = gradients.data();
    double* residual = residuals.data();
    for (int iteration = 0;; ++iteration) {
      NormalSums<P> sums;
      double sum_of_squares = 0.0;
      for (size_t j = 0; j < n; ++j) {
        const Eigen::Vector3d& q = points[j];
        const Eigen::Vector3d& d = beams[j];
        double per_metre = s.rise(q.x(), q.y(), d);
        if (std::abs(per_metre) < kMaxCosGrazing) per_metre = std::copysign(kMaxCosGrazing, per_metre);
        const double e = (q.z() - s.height(q.x(), q.y())) / per_metre;  // metres along the beam
        residual[j] = e;
        sum_of_squares += e * e;
        // d residual / d c: the basis where the point's beam meets the surface, over per_metre.
        gradient[j] = Terms::basis(q.x() - e * d.x(), q.y() - e * d.y()).over(per_metre);
        sums.add(gradient[j], e);
      }
      rss = sum_of_squares;
      Eigen::Matrix<double, 6, 1> step;
      if (!solve_normal_equations<P>(sums.matrix(), sums.right(), step, &inverse)) return false;
      if (iteration == 3) break;  // three steps from the height fit: converged to well below its error
      s.c += step;
      if (iteration + 1 == steps) return s.c.allFinite();
    }
    NormalSums<P> meat_sums;
    for (size_t j = 0; j < n; ++j) meat_sums.add_weighted(gradient[j], residual[j] * residual[j]);
    Eigen::Matrix<double, 6, 6> meat = meat_sums.matrix();
    symmetric(meat);
    const double dof = static_cast<double>(n) / static_cast<double>(n - static_cast<size_t>(P));
    s.covariance = dof * inverse * meat * inverse;
    return s.covariance.allFinite() && s.c.allFinite();
  }

  // The points of frames k - n .. k + n but k within `radius` of x, from a window of rows x columns
  // around where x falls in each; returns how many frames gave some. Within a frame: frame k's own
  // points but pixel `own` (its index in frame k). The window is stepped through `stride` pixels at
  // a time; by default every other one where it is at its widest (kMaxPatchRows or
  // kMaxPatchColumns), else every one.
  size_t gather(size_t k, size_t own, const Eigen::Vector3f& x, double radius, int rows, int columns, Patch& points,
                int stride = 0) const {
    const auto radius2 = static_cast<float>(radius * radius);
    points.clear();
    size_t frames_used = 0;
    const size_t reach = within_frame_ ? 0 : static_cast<size_t>(neighbour_frames_);
    const size_t first = k >= reach ? k - reach : 0;
    const size_t last = std::min(frames_.size() - 1, k + reach);
    if (stride <= 0) stride = rows >= kMaxPatchRows || columns >= kMaxPatchColumns ? 2 : 1;
    for (size_t j = first; j <= last; ++j) {
      if (j == k && !within_frame_) continue;
      const FramePoints& other = frames_[j];
      const BeamProjector::Pixel seed = projector_.project_world(other, x);
      const size_t before = points.size();
      for (int dm = -columns; dm <= columns; dm += stride) {
        for (int dr = -rows; dr <= rows; dr += stride) {
          const std::optional<BeamProjector::Pixel> near = projector_.beside(seed.m, seed.r, dm, dr);
          if (!near) continue;
          const size_t t = other.index(near->m, near->r);
          if ((j == k && t == own) || !other.returned(t) || (other.world[t] - x).squaredNorm() > radius2) continue;
          points.points.push_back(other.world[t].cast<double>());
          points.beams.push_back(
              (other.rotation[static_cast<size_t>(near->m)] * projector_.direction(near->m, near->r)).cast<double>());
        }
      }
      frames_used += points.size() > before;
    }
    return frames_used;
  }

  // The incidence at grazing, from a plane through a strip of the surface along the beam. There the
  // beams' crossings lie range x spacing / cos theta apart along the beam (the ground at 82 degrees
  // and 10 m: 0.9 m between an OS1-64's scan lines), and a patch of the reference's size holds one
  // line of them from each frame: its slope along the beam, and so the incidence that E4's steep
  // spread rests on, scattered by degrees (the plant drive's ground at 80-85 degrees and 8-13 m, with
  // the shipped os1-64: 5 % of the returns 4.8 degrees low or more, E4's spread predicted 14 % low
  // in z^2 on average, map mode's spread ratio 1.11 of the scene's). A plane through 2.5 spacings
  // either side along the beam, one pixel either side across it, takes the slope from several lines
  // (there: 95 % within -0.45..+0.5 degrees, the ratio 1.02). None where the patch holds more than
  // two lines along the beam, or the strip makes no plane.
  // Overwrites the patch's points (local_, beams_): the reference is fitted by then.
  std::optional<double> strip_cos_incidence(size_t k, int m, int r, const Surface& s, double u, double v,
                                            const Eigen::Vector3d& d, double cos_local, double range,
                                            double kept_radius, Patch& points) const {
    const double spacing = std::max(projector_.row_spacing_rad(), projector_.column_spacing_rad());
    const double step = range * spacing / std::max(cos_local, kMaxCosGrazing);  // between crossings along the beam
    if (step <= kept_radius) return std::nullopt;
    const double radius = std::min(kStripSpacings * step, kMaxStripM);
    // Plane through the crossing with the surface's slope there, in the surface's frame.
    Surface plane = s;
    const Eigen::Vector2d g = s.slope(u, v);
    const double h = s.height(u, v);
    plane.terms = 3;
    plane.c << h - g.x() * u - g.y() * v, g.x(), g.y(), 0.0, 0.0, 0.0;
    // The strip's window: where its ends fall in the pixel's own frame.
    Eigen::Vector3d along(d.x(), d.y(), g.x() * d.x() + g.y() * d.y());
    if (along.squaredNorm() < 1e-12) return std::nullopt;
    along.normalize();
    const Eigen::Vector3d crossing(u, v, h);
    const auto world = [&](const Eigen::Vector3d& q) {
      return s.centre + q.x() * s.e_u + q.y() * s.e_v + q.z() * s.e_w;
    };
    const FramePoints& f = frames_[k];
    // One pixel either side across the beam: the slope across it hardly moves the incidence there.
    // Columns are counted in azimuth (beside()), not measurement id: rows have azimuth offsets.
    int strip_rows = 1, strip_columns = 1;
    for (const double sign : {-1.0, 1.0}) {
      const BeamProjector::Pixel end =
          projector_.project_world(f, world(crossing + sign * radius * along).cast<float>());
      const std::optional<BeamProjector::Pixel> level = projector_.beside(m, r, 0, end.r - r);
      if (!level) continue;
      int dm = std::abs(end.m - level->m);
      dm = std::min(dm, f.width - dm);
      strip_rows = std::max(strip_rows, std::abs(end.r - r) + 1);
      strip_columns = std::max(strip_columns, dm + 1);
    }
    strip_rows = std::min(strip_rows, kMaxPatchRows);
    strip_columns = std::min(strip_columns, kMaxPatchColumns);
    gather(k, f.index(m, r), world(crossing).cast<float>(), radius, strip_rows, strip_columns, points, 1);
    if (!select_by_beams(points, plane, crossing, radius, HeightCut::kStrip)) return std::nullopt;
    double rss = 0.0;
    if (!gauss_newton(plane, 3, rss, kStripSteps)) return std::nullopt;
    const Eigen::Vector3d normal = Eigen::Vector3d(-plane.c(1), -plane.c(2), 1.0).normalized();
    return std::abs(normal.dot(d));
  }

  // How far apart the scan lines lie on the surface at pixel (m, r): half the distance between the
  // points of the rows above and below it, as measured (the fitted surface's normal would say, but
  // where the lines are far apart it is what tilts: the ground at 83 degrees read 77). None when
  // one of them is past the frame's rows or did not return.
  std::optional<double> scan_line_step(const FramePoints& f, int m, int r) const {
    const std::optional<BeamProjector::Pixel> above = projector_.beside(m, r, 0, -1);
    const std::optional<BeamProjector::Pixel> below = projector_.beside(m, r, 0, 1);
    if (!above || !below) return std::nullopt;
    const size_t a = f.index(above->m, above->r), b = f.index(below->m, below->r);
    if (!f.returned(a) || !f.returned(b)) return std::nullopt;
    return 0.5 * static_cast<double>((f.world[a] - f.world[b]).norm());
  }

  // The normal of the pixel's own frame's points within `half` of it (world frame), when they
  // make a patch.
  std::optional<Eigen::Vector3d> own_frame_normal(const FramePoints& f, int m, int r, double half) const {
    const Eigen::Vector3f& centre = f.world[f.index(m, r)];
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
    int n = 0;
    for (int dm = -2 * column_reach_; dm <= 2 * column_reach_; ++dm) {
      for (int dr = -2; dr <= 2; ++dr) {
        const std::optional<BeamProjector::Pixel> p = projector_.beside(m, r, dm, dr);
        if (!p) continue;
        const size_t j = f.index(p->m, p->r);
        if (!f.returned(j) || static_cast<double>((f.world[j] - centre).norm()) > 1.5 * half) continue;
        const Eigen::Vector3d d = (f.world[j] - centre).cast<double>();
        sum += d;
        outer += d * d.transpose();
        ++n;
      }
    }
    if (n < 8) return std::nullopt;
    const Eigen::Vector3d mean = sum / n;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(outer / n - mean * mean.transpose());
    const Eigen::Vector3d values = eigen.eigenvalues();
    if (!(values(1) > 0.0) || values(1) < 0.05 * values(2) || values(0) > values(1) / 9.0) return std::nullopt;
    return eigen.eigenvectors().col(0);
  }

  const std::vector<FramePoints>& frames_;
  const BeamProjector& projector_;
  int neighbour_frames_;
  bool within_frame_;
  int column_reach_ = 1;
};

struct KeptPixel {
  uint16_t m = 0, r = 0;
  Crossing reference;
};

}  // namespace

MapTable build_map_table(const MapTableSetup& setup, WorkerPool& pool) {
  const MeasuredCapture& capture = setup.capture;
  const Metadata& metadata = capture.metadata;
  const LidarDataFormat& format = metadata.format;
  if (capture.frames.empty()) throw InputError("--map: the capture has no complete frame");
  if (capture.frames.size() < 2 && !setup.within_frame) {
    throw InputError(
        fmt::format("--map: the capture has {} frame; a reference from other frames needs at least 2 "
                    "(--within-frame makes it from the frame's own returns)",
                    capture.frames.size()));
  }
  std::vector<FramePoints> frames = analysis_detail::capture_points(capture);
  const PoseSpan span = setup.poses.span();
  for (size_t k = 0; k < frames.size(); ++k) {
    for (const double t : {frames[k].start_s, frames[k].end_s}) {
      if (std::isfinite(t) && !span.contains(t + setup.time_offset_s)) {
        throw InputError(fmt::format(
            "--pose: frame {} was measured at {:.6f} s (capture clock), outside the poses' span [{:.6f}, {:.6f}] s", k,
            t, span.begin_s, span.end_s));
      }
    }
    analysis_detail::place(frames[k], setup.poses, setup.time_offset_s);
  }
  const size_t scored_begin = setup.first_scored_frame;
  const size_t scored_end =
      setup.scored_frames == 0 ? frames.size() : std::min(frames.size(), scored_begin + setup.scored_frames);
  if (scored_begin >= frames.size()) {
    throw InputError(fmt::format("--skip-frames {}: the capture has only {} frame{}", scored_begin, frames.size(),
                                 frames.size() == 1 ? "" : "s"));
  }
  const BeamProjector projector(metadata);
  const MapReferences references(frames, projector, setup.neighbour_frames, setup.within_frame);
  const PacketFormat packets(format);
  const double reach = cast_reach_m(setup.max_range_m, packets);

  // Frame by frame (any thread), then gathered in frame order: the table does not depend on threads.
  std::vector<std::vector<KeptPixel>> kept(frames.size());
  std::vector<MapExclusions> counts(frames.size());
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  pool.run(static_cast<int>(frames.size()), [&](int, int item) {
    const auto k = static_cast<size_t>(item);
    const FramePoints& f = frames[k];
    MapExclusions& c = counts[k];
    Patch points;
    const int width = k >= scored_begin && k < scored_end ? f.width : 0;  // a reference only
    for (int m = 0; m < width; ++m) {
      for (int r = 0; r < f.height; ++r) {
        const size_t i = f.index(m, r);
        if (!f.returned(i) || static_cast<double>(f.range_m[i]) > setup.max_range_m) continue;
        ++c.returns;
        Crossing ref;
        switch (references.reference(k, m, r, ref, points)) {
          case Verdict::kCompared:
            ++c.compared;
            kept[k].push_back({static_cast<uint16_t>(m), static_cast<uint16_t>(r), ref});
            break;
          case Verdict::kEdge: ++c.edge; break;
          case Verdict::kUnsupported: ++c.unsupported; break;
          case Verdict::kNotSurface: ++c.not_surface; break;
          case Verdict::kOffSurface: ++c.off_surface; break;
          case Verdict::kGrazing: ++c.grazing; break;
        }
      }
    }
    const int now = ++done;
    if (setup.progress) {
      const std::lock_guard lock(progress_mutex);
      setup.progress(static_cast<double>(now) / static_cast<double>(frames.size()));
    }
  });
  MapTable out;
  size_t total = 0;
  for (size_t k = 0; k < frames.size(); ++k) {
    const MapExclusions& c = counts[k];
    out.excluded.returns += c.returns;
    out.excluded.compared += c.compared;
    out.excluded.edge += c.edge;
    out.excluded.unsupported += c.unsupported;
    out.excluded.not_surface += c.not_surface;
    out.excluded.off_surface += c.off_surface;
    out.excluded.grazing += c.grazing;
    total += kept[k].size();
  }
  if (total == 0) {
    throw InputError(fmt::format(
        "--map: no return of the {} could be compared: none lies on a smooth surface that other frames saw ({} "
        "beside depth steps, {} with too few points of other frames around them, {} on no smooth surface, {} far "
        "from it); is the trajectory right?",
        out.excluded.returns, out.excluded.edge, out.excluded.unsupported, out.excluded.not_surface,
        out.excluded.off_surface));
  }

  PixelTable& t = out.table;
  t.reference = PixelTable::Reference::kMap;
  t.resize(total);
  t.context = wire_context(packets, analysis_detail::signal_gain_of(metadata));
  double first = std::numeric_limits<double>::infinity();
  for (const FramePoints& f : frames) first = std::min(first, f.start_s);
  t.start_s = capture.start_ns != 0 ? std::min(first, static_cast<double>(capture.start_ns) * 1e-9) : first;
  const bool has_reflectivity = packets.has_channel(ChannelField::kReflectivity);
  std::vector<size_t> offsets(frames.size() + 1, 0);
  for (size_t k = 0; k < frames.size(); ++k) offsets[k + 1] = offsets[k] + kept[k].size();
  pool.run(static_cast<int>(frames.size()), [&](int, int item) {
    const auto k = static_cast<size_t>(item);
    const Scan& scan = capture.frames[k].scan;
    for (size_t n = 0; n < kept[k].size(); ++n) {
      const KeptPixel& pixel = kept[k][n];
      const size_t p = offsets[k] + n;
      t.set_measured(p, static_cast<uint32_t>(k - scored_begin), scan, pixel.m, pixel.r);
      IdealReturn ideal;
      ideal.range_m = pixel.reference.range_m;
      ideal.cos_incidence = pixel.reference.cos_incidence;
      // REFLECTIVITY is the apparent reflectivity rho cos(theta) in percent for Lambertian targets
      // (lidar-physics.md 2.1); the material's own is what the radiometry takes.
      ideal.reflectivity =
          has_reflectivity ? std::clamp(t.reflectivity[p] / 100.0f / std::max(ideal.cos_incidence, 0.1f), 0.01f, 1.0f)
                           : 0.5f;
      ideal.beam = pixel.r;
      t.set_ideal(p, ideal);
      t.material[p] = 0xFFFF;  // no scene: no material, no retroreflectors; edges were left out
      t.edge[p] = t.retro[p] = PixelTable::kFarPixels;
      t.reference_scale[p] = 1.0f;
      t.reference_variance_m2[p] = pixel.reference.variance_m2;
      t.step_m[p] = t.context.range_step_m;
      t.window_max_m[p] = static_cast<float>(reach);
      t.predict(p, setup.chain);
    }
  });
  for (size_t i = 0; i < t.size(); ++i) {
    if (t.predicted_sigma_m[i] <= 0.0f) {
      throw InputError(
          "--profile: its effect chain predicts no range spread (variance 0), so map mode has nothing to compare "
          "the measured spread with");
    }
  }
  return out;
}

}  // namespace lidartwin
