// E1(b): zero-mean Gaussian range noise whose standard deviation is a continuous piecewise-linear
// function of the true range through knots (r_k, sigma_k), constant beyond the first and last
// knot. This is the paper's proposed future work (Tejero et al., Section V) and lets a profile
// follow the datasheet precision table (the paper's Table I) instead of the B0 line: plateaus at
// the table's values joined by short ramps at the bin edges (see profiles/os1-64.json).
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "effects/builtin_effects.h"
#include "effects/gaussian_range_noise.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

constexpr Bounds kKnotRange{0.0, 10000.0};
constexpr Bounds kKnotSigma{1e-6, 10.0};  // sigma > 0

struct Knot {
  double range_m;
  double sigma_m;
};

// `at` is the effect's object: points_m/<index>/<component> inside it.
Location knot_location(const Location& at, size_t index, size_t component) {
  return at.child("points_m").child(index).child(component);
}

void check_knots(const std::vector<Knot>& knots, const Location& at) {
  if (knots.size() < 2) at.child("points_m").fail("needs at least 2 knots [range_m, sigma_m]");
  for (size_t k = 0; k < knots.size(); ++k) {
    check_number(knots[k].range_m, knot_location(at, k, 0), kKnotRange);
    check_number(knots[k].sigma_m, knot_location(at, k, 1), kKnotSigma);
    if (k > 0 && !(knots[k].range_m > knots[k - 1].range_m)) {
      knot_location(at, k, 0).fail("must be greater than the previous knot's range " +
                                   format_number(knots[k - 1].range_m) + ", got " + format_number(knots[k].range_m));
    }
  }
}

std::vector<Knot> read_knots(const nlohmann::json& params, const Location& at) {
  static constexpr std::array<std::string_view, 1> kKeys{"points_m"};
  check_keys(params, at, "range_noise_piecewise", kKeys);
  const Location where = at.child("points_m");
  const auto points = params.find("points_m");
  if (points == params.end()) where.fail("missing; range_noise_piecewise needs [[range_m, sigma_m], ...]");
  if (!points->is_array()) where.fail("must be an array of [range_m, sigma_m] pairs");
  std::vector<Knot> knots;
  for (size_t k = 0; k < points->size(); ++k) {
    const auto& pair = (*points)[k];
    if (!pair.is_array() || pair.size() != 2) where.child(k).fail("must be [range_m, sigma_m]");
    knots.push_back({read_number(pair[0], knot_location(at, k, 0), kKnotRange),
                     read_number(pair[1], knot_location(at, k, 1), kKnotSigma)});
  }
  check_knots(knots, at);
  return knots;
}

class RangeNoisePiecewise final : public GaussianRangeNoise<RangeNoisePiecewise, Effect> {
 public:
  static constexpr std::string_view kName = "range_noise_piecewise";

  explicit RangeNoisePiecewise(std::vector<Knot> knots) : knots_(std::move(knots)) {
    // Segment 0 holds r <= the first knot, segment i (1 <= i < n) lies between knots i - 1 and i,
    // segment n holds r >= the last knot; r leaves segment i for i + 1 where r > bounds_[i].
    const size_t n = knots_.size();
    segments_.push_back({knots_.front().sigma_m, 0.0, knots_.front().range_m});
    for (size_t k = 0; k + 1 < n; ++k) {
      const double slope = (knots_[k + 1].sigma_m - knots_[k].sigma_m) / (knots_[k + 1].range_m - knots_[k].range_m);
      segments_.push_back({knots_[k].sigma_m, slope, knots_[k].range_m});
      bounds_.push_back(knots_[k].range_m);
    }
    segments_.push_back({knots_.back().sigma_m, 0.0, knots_.back().range_m});
    bounds_.push_back(std::nextafter(knots_.back().range_m, -HUGE_VAL));  // r >= the last knot
    for (uint32_t b = 0; b < kBuckets; ++b) {
      const double lower = b == 0 ? -HUGE_VAL : bucket_start(b);
      const double upper = b + 1 == kBuckets ? HUGE_VAL : bucket_start(b + 1);
      const auto below = std::lower_bound(bounds_.begin(), bounds_.end(), lower);
      const auto inside = std::lower_bound(below, bounds_.end(), upper);
      first_segment_[b] = static_cast<uint32_t>(below - bounds_.begin());
      bounds_per_bucket_ = std::max(bounds_per_bucket_, static_cast<size_t>(inside - below));
    }
    bounds_.resize(bounds_.size() + bounds_per_bucket_, HUGE_VAL);  // the last bucket's comparisons read past
  }

  std::string_view name() const override { return kName; }

  // The segment from its bucket's first and a fixed count of comparisons, added, not branched on:
  // ranges in a column jump between floor, walls and sky, and a search by branches mispredicted
  // (a fifth of the effect's time from the ground pose). The two outer segments have slope 0, so
  // they give the end knots' sigma exactly.
  double sigma(float range_m) const {
    const double r = static_cast<double>(range_m);
    size_t i = first_segment_[bucket(range_m)];
    const double* bound = bounds_.data() + i;
    for (size_t k = 0; k < bounds_per_bucket_; ++k) i += static_cast<size_t>(r > bound[k]);
    const Segment& s = segments_[i];
    return s.sigma_m + s.slope * (r - s.range_m);
  }

  // Knot ranges are structure (fixed); the sigmas are what a fit adjusts.
  std::vector<EffectParameter> parameters() const override {
    std::vector<EffectParameter> out;
    for (size_t k = 0; k < knots_.size(); ++k) {
      const std::string prefix = "points_m/" + std::to_string(k);
      out.push_back({prefix + "/0", knots_[k].range_m, kKnotRange.lower, kKnotRange.upper, true});
      out.push_back({prefix + "/1", knots_[k].sigma_m, kKnotSigma.lower, kKnotSigma.upper, false});
    }
    return out;
  }

  std::unique_ptr<Effect> with_parameters(std::span<const double> values) const override {
    if (values.size() % 2 != 0) fitted(kName).fail("expected [range_m, sigma_m] pairs, got an odd count of values");
    std::vector<Knot> knots;
    for (size_t i = 0; i + 1 < values.size(); i += 2) knots.push_back({values[i], values[i + 1]});
    check_knots(knots, fitted(kName));
    auto copy = std::make_unique<RangeNoisePiecewise>(std::move(knots));
    copy->set_stream_id(stream_id());
    return copy;
  }

 private:
  // A bucket per eighth of an octave (by the float's exponent and top 3 mantissa bits, 2^-6 to
  // 2^10 m; the first and last take everything below and above) remembers the segment at its
  // start, leaving one comparison per bound inside a bucket (one for the datasheet's knots).
  static constexpr uint32_t kBuckets = 16 * 8 + 1;
  static constexpr uint32_t kBucketShift = 23 - 3;
  static constexpr uint32_t kMinBits = 0x3C800000u;  // 2^-6 as a float
  static uint32_t bucket(float r) {
    const uint32_t bits = std::bit_cast<uint32_t>(std::clamp(r, 0x1.0p-6f, 0x1.0p10f));
    return (bits - kMinBits) >> kBucketShift;
  }
  static double bucket_start(uint32_t b) {
    return static_cast<double>(std::bit_cast<float>(kMinBits + (b << kBucketShift)));
  }
  struct Segment {
    double sigma_m;  // at range_m
    double slope;
    double range_m;
  };

  std::vector<Knot> knots_;
  std::vector<Segment> segments_;  // n + 1 for n knots
  std::vector<double> bounds_;     // n, then +inf padding
  std::array<uint32_t, kBuckets> first_segment_{};
  size_t bounds_per_bucket_ = 0;  // the most bounds inside one bucket
};

}  // namespace

std::unique_ptr<Effect> make_range_noise_piecewise(const nlohmann::json& params, const Location& at) {
  return std::make_unique<RangeNoisePiecewise>(read_knots(params, at));
}

// A noise law (noise_laws.h), as range_noise_linear.
EffectCard range_noise_piecewise_card() { return {.catalogue = "E1"}; }

}  // namespace lidartwin::effects_detail
