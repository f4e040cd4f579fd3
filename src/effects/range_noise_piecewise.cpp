// E1(b): zero-mean Gaussian range noise whose standard deviation is a continuous piecewise-linear
// function of the true range through knots (r_k, sigma_k), constant beyond the first and last
// knot. This is the paper's proposed future work (Tejero et al., Section V) and lets a profile
// follow the datasheet precision table (the paper's Table I) instead of the B0 line: plateaus at
// the table's values joined by short ramps at the bin edges (see profiles/os1-64.json).
#include <algorithm>
#include <bit>
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

std::string knot_path(std::string_view source, size_t index, int component) {
  return json_path(json_path(json_path(source, "points_m"), std::to_string(index)), std::to_string(component));
}

void check_knots(const std::vector<Knot>& knots, std::string_view source) {
  if (knots.size() < 2) fail(json_path(source, "points_m"), "needs at least 2 knots [range_m, sigma_m]");
  for (size_t k = 0; k < knots.size(); ++k) {
    check_number(knots[k].range_m, knot_path(source, k, 0), kKnotRange);
    check_number(knots[k].sigma_m, knot_path(source, k, 1), kKnotSigma);
    if (k > 0 && !(knots[k].range_m > knots[k - 1].range_m)) {
      fail(knot_path(source, k, 0), "must be greater than the previous knot's range " +
                                        format_number(knots[k - 1].range_m) + ", got " +
                                        format_number(knots[k].range_m));
    }
  }
}

std::vector<Knot> read_knots(const nlohmann::json& params, std::string_view source) {
  static constexpr std::array<std::string_view, 1> kKeys{"points_m"};
  check_keys(params, source, "range_noise_piecewise", kKeys);
  const std::string where = json_path(source, "points_m");
  const auto points = params.find("points_m");
  if (points == params.end()) fail(where, "missing; range_noise_piecewise needs [[range_m, sigma_m], ...]");
  if (!points->is_array()) fail(where, "must be an array of [range_m, sigma_m] pairs");
  std::vector<Knot> knots;
  for (size_t k = 0; k < points->size(); ++k) {
    const auto& pair = (*points)[k];
    if (!pair.is_array() || pair.size() != 2) fail(json_path(where, std::to_string(k)), "must be [range_m, sigma_m]");
    knots.push_back({read_number(pair[0], knot_path(source, k, 0), kKnotRange),
                     read_number(pair[1], knot_path(source, k, 1), kKnotSigma)});
  }
  check_knots(knots, source);
  return knots;
}

class RangeNoisePiecewise final : public GaussianRangeNoise<RangeNoisePiecewise, Effect> {
 public:
  static constexpr std::string_view kName = "range_noise_piecewise";

  explicit RangeNoisePiecewise(std::vector<Knot> knots) : knots_(std::move(knots)) {
    for (size_t k = 0; k + 1 < knots_.size(); ++k) {
      slopes_.push_back((knots_[k + 1].sigma_m - knots_[k].sigma_m) / (knots_[k + 1].range_m - knots_[k].range_m));
    }
    for (uint32_t b = 0; b < first_segment_.size(); ++b) {
      first_segment_[b] = static_cast<uint8_t>(std::min<size_t>(segment_scan(0, bucket_start(b)), 255));
    }
  }

  std::string_view name() const override { return kName; }

  double sigma(float range_m) const {
    const double r = static_cast<double>(range_m);
    if (r <= knots_.front().range_m) return knots_.front().sigma_m;
    if (r >= knots_.back().range_m) return knots_.back().sigma_m;
    const size_t k = segment_scan(first_segment_[bucket(range_m)], r);
    return knots_[k].sigma_m + slopes_[k] * (r - knots_[k].range_m);
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
    if (values.size() % 2 != 0) fail(kName, "expected [range_m, sigma_m] pairs, got an odd count of values");
    std::vector<Knot> knots;
    for (size_t i = 0; i + 1 < values.size(); i += 2) knots.push_back({values[i], values[i + 1]});
    check_knots(knots, kName);
    auto copy = std::make_unique<RangeNoisePiecewise>(std::move(knots));
    copy->set_stream_id(stream_id());
    return copy;
  }

 private:
  // Ranges in a column jump between floor, walls and sky, so a scan from the first knot would
  // mispredict; a bucket per eighth of an octave (by the float's exponent and top 3 mantissa
  // bits, 2^-6 to 2^10 m) remembers the segment at its start, leaving about one comparison.
  static constexpr uint32_t kBucketShift = 23 - 3;
  static constexpr uint32_t kMinBits = 0x3C800000u;  // 2^-6 as a float
  static uint32_t bucket(float r) {
    const uint32_t bits = std::bit_cast<uint32_t>(std::clamp(r, 0x1.0p-6f, 0x1.0p10f));
    return (bits - kMinBits) >> kBucketShift;
  }
  static double bucket_start(uint32_t b) {
    return static_cast<double>(std::bit_cast<float>(kMinBits + (b << kBucketShift)));
  }
  // The segment k (knot k to k+1) holding r, searching forward from `k`.
  size_t segment_scan(size_t k, double r) const {
    while (k + 2 < knots_.size() && r > knots_[k + 1].range_m) ++k;
    return k;
  }

  std::vector<Knot> knots_;
  std::vector<double> slopes_;
  std::array<uint8_t, 16 * 8 + 1> first_segment_{};
};

}  // namespace

std::unique_ptr<Effect> make_range_noise_piecewise(const nlohmann::json& params, std::string_view source) {
  return std::make_unique<RangeNoisePiecewise>(read_knots(params, source));
}

}  // namespace lidartwin::effects_detail
