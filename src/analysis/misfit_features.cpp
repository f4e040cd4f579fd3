// The features the misfit is binned over, and the per-pixel model (misfit_features.h).
#include "analysis/misfit_features.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

namespace lidartwin::analysis_detail {

RangeModel model_of(const PixelTable& t, size_t i) {
  RangeModel m;
  m.mean_m = (f64(t.ideal_range_m[i])) + f64(t.predicted_bias_m[i]);
  m.sigma_m = f64(t.predicted_sigma_m[i]);
  m.p_detect = f64(t.p_detect[i]);
  m.outlier_mix = f64(t.outlier_mix[i]);
  m.partner_mix = f64(t.partner_mix[i]);
  m.partner_offset_m = f64(t.partner_offset_m[i]);
  m.partner_sigma_m = f64(t.partner_sigma_m[i]);
  m.tail_mix = f64(t.tail_mix[i]);
  m.tail_sigma_m = f64(t.tail_sigma_m[i]);
  m.window_min_m = f64(t.window_min_m[i]);
  m.window_max_m = f64(t.window_max_m[i]);
  m.step_m = f64(t.step_m[i]);
  return m;
}

double expected_outlier_share(const PixelTable& t, size_t i) {
  // Returns from an edge partner (E6) a depth step away, or a halo's (E8) at a retroreflector's
  // range, fall outside the pixel's own Gaussian too, as do E2's tails: the share of each component
  // beyond the bounds.
  const RangeModel m = model_of(t, i);
  const double share = partner_share(m);
  const double bound = kOutlierZ * m.sigma_m;
  double partner_out = 0.0;
  if (share > 0.0) {
    const double sigma = m.partner_sigma();
    partner_out = 1.0 - normal_interval((-bound - m.partner_offset_m) / sigma, (bound - m.partner_offset_m) / sigma);
  }
  const double tail = (1.0 - share) * std::clamp(m.tail_mix, 0.0, 1.0);
  const double tail_out = tail > 0.0 ? 1.0 - normal_interval(-bound / m.tail_sigma_m, bound / m.tail_sigma_m) : 0.0;
  const double core = 1.0 - share - tail;
  const double pi = std::clamp(m.outlier_mix, 0.0, 1.0);
  return pi + (1.0 - pi) * (core * 2.0 * normal_cdf(-kOutlierZ) + share * partner_out + tail * tail_out);
}

InlierMoments inlier_moments(const PixelTable& t, size_t i) {
  const double tail = std::clamp(f64(t.tail_mix[i]), 0.0, 1.0);
  const double k = f64(t.tail_sigma_m[i]) / f64(t.predicted_sigma_m[i]);  // the tail's sigma in the core's
  if (tail <= 0.0 || !(k > 0.0) || !std::isfinite(k)) return {};
  // A standard normal's share inside +-a and its second and fourth moments there, for the tail's
  // a = kOutlierZ / k (the core's: 1 and 3 of nearly all).
  const double a = kOutlierZ / k;
  const double density = std::exp(-0.5 * a * a) / std::sqrt(2.0 * std::numbers::pi);
  const double inside = 1.0 - 2.0 * normal_cdf(-a);
  const double second = inside - 2.0 * a * density;
  const double fourth = 3.0 * second - 2.0 * a * a * a * density;
  const double mass = (1.0 - tail) + tail * inside;
  return {((1.0 - tail) + tail * k * k * second) / mass, (3.0 * (1.0 - tail) + tail * k * k * k * k * fourth) / mass};
}

double inlier_z2(const PixelTable& t, size_t i) { return inlier_moments(t, i).z2; }

int Feature::bin(double v) const {
  const auto it = std::upper_bound(edges.begin(), edges.end(), v);
  const auto k = static_cast<int>(it - edges.begin()) - 1;
  return k >= 0 && k + 1 < static_cast<int>(edges.size()) ? k : -1;
}

std::array<double, 2> Feature::range_of(int k) const {
  const auto u = static_cast<size_t>(k);
  return {edges[u], integer ? edges[u + 1] - 1 : edges[u + 1]};
}

namespace {

constexpr size_t kMaxMaterials = 64;  // beyond this, materials are not binned one by one

std::vector<double> integer_edges(int first, int last, int step) {
  std::vector<double> edges;
  for (int v = first; v <= last; v += step) edges.push_back(v);
  if (edges.back() < last + 1) edges.push_back(last + 1);
  return edges;
}

}  // namespace

Features make_features(const PixelTable& t) {
  Features f;
  const auto add = [&](Feature feature) { f.by_name.emplace(feature.name, std::move(feature)); };
  add({"range", {0, 1, 2, 3, 5, 8, 13, 20, 35, 60, 100, 200, 1e4}, false, [&t](size_t i) {
         return f64(t.ideal_range_m[i]);
       }});
  // Values at a closed upper end (90°, 360°) are kept in the last bin.
  add({"incidence", {0, 30, 45, 60, 75, 90}, false, [&t](size_t i) {
         return std::min(f64(t.incidence_deg[i]), 89.999);
       }});
  add({"reflectivity", {0, 5, 10, 20, 40, 60, 80, 1e4}, false, [&t](size_t i) {
         return 100.0 * f64(t.material_reflectivity[i]);
       }});
  add({"signal", {0, 10, 30, 100, 300, 1000, 3000, 10000, 1e12}, false, [&t](size_t i) {
         return f64(t.expected_signal[i]);
       }});
  add({"near_ir", {0, 10, 30, 100, 300, 1000, 3000, 10000, 1e12}, false, [&t](size_t i) {
         return f64(t.expected_near_ir[i]);
       }});
  add({"azimuth", {0, 45, 90, 135, 180, 225, 270, 315, 360}, false, [&t](size_t i) {
         return std::min(f64(t.azimuth_deg[i]), 359.999);
       }});
  // Pixel distances (lidar-physics.md 3.2: 0, 1, 2, 3-5, more than 5).
  add({"edge", {0, 1, 2, 3, 6, 7}, true, [&t](size_t i) { return t.edge[i]; }});
  add({"retro", {0, 1, 2, 3, 6, 7}, true, [&t](size_t i) { return t.retro[i]; }});
  int beams = 0;
  for (const uint16_t b : t.beam) beams = std::max(beams, b + 1);
  add({"beam", integer_edges(0, beams - 1, 1), true, [&t](size_t i) { return t.beam[i]; }, false});
  add({"beam_group", integer_edges(0, beams - 1, 8), true, [&t](size_t i) { return t.beam[i]; }, false});
  double t0 = 0.0, t1 = 0.0;
  if (t.size() > 0) {
    const auto [lo, hi] = std::minmax_element(t.time_s.begin(), t.time_s.end());
    t0 = *lo;
    t1 = *hi;
  }
  std::vector<double> time_edges;
  for (int k = 0; k <= 5; ++k) time_edges.push_back((t1 - t0) * k / 5.0);
  time_edges.back() = std::nextafter(time_edges.back(), 1e300);
  add({"time", time_edges, false, [&t, t0](size_t i) { return t.time_s[i] - t0; }});
  std::set<uint16_t> materials;
  for (size_t i = 0; i < t.size() && materials.size() <= kMaxMaterials; ++i) {
    if (t.ideal_range_m[i] > 0.0f) materials.insert(t.material[i]);
  }
  if (materials.size() <= kMaxMaterials && !materials.empty()) {
    add({"material", integer_edges(0, *materials.rbegin(), 1), true, [&t](size_t i) { return t.material[i]; }, false});
  }
  return f;
}

}  // namespace lidartwin::analysis_detail
