#pragma once
// What the misfit bins (misfit.cpp) and the unexplained-misfit search (unexplained.cpp) share: the
// features of the compare vocabulary as bins over the pixel table, and the per-pixel model.
#include <array>
#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "lidartwin/analysis/pixel_likelihood.h"
#include "lidartwin/analysis/pixel_table.h"

namespace lidartwin::analysis_detail {

inline constexpr double kOutlierZ = 5.0;  // a return this many sigma off counts as an outlier, not spread
inline constexpr size_t kMinTested = 30;  // smaller bins are reported but not tested

// The table stores floats; sums and tests run in double.
inline double f64(float v) { return static_cast<double>(v); }

// Pixel i's predicted distribution of the measured range, as the table holds it.
RangeModel model_of(const PixelTable& t, size_t i);
// The probability that return i lies beyond kOutlierZ sigma under the model (outlier components,
// an edge partner a depth step away, the Gaussian's own tails).
double expected_outlier_share(const PixelTable& t, size_t i);
// E[z^2] of return i given that it is an inlier (|z| <= kOutlierZ, z in the core's sigmas): 1, but
// where E2's tails put a share of the returns in a wider Gaussian, some of which fall inside.
double inlier_z2(const PixelTable& t, size_t i);
// E[z^2] and E[z^4] of return i given that it is an inlier, as inlier_z2: (1, 3) for the core alone.
// The bias test's variance is the first; the spread test's (the variance of z^2) is z4 - z2^2,
// which E2's tails make several times a Gaussian's 2.
struct InlierMoments {
  double z2 = 1.0;
  double z4 = 3.0;
};
InlierMoments inlier_moments(const PixelTable& t, size_t i);

struct Feature {
  std::string name;
  std::vector<double> edges;  // bin k is [edges[k], edges[k + 1])
  bool integer = false;       // integer-valued: a bin's region is [lo, hi - 1]
  std::function<double(size_t)> value;
  bool ordered = true;      // false: categories (beam, material), where "grows with" means nothing
  int bin(double v) const;  // -1 outside the edges
  int bins() const { return static_cast<int>(edges.size()) - 1; }
  std::array<double, 2> range_of(int k) const;
};

struct Features {
  std::map<std::string, Feature> by_name;
  const Feature& operator[](const std::string& name) const { return by_name.at(name); }
  bool has(const std::string& name) const { return by_name.count(name) > 0; }
};

// Every feature of the table (range, incidence, reflectivity, signal, near_ir, azimuth, edge,
// retro, beam, beam_group, time, and material when the scene has few enough).
Features make_features(const PixelTable& t);

}  // namespace lidartwin::analysis_detail
