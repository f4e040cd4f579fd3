// E5 (its range part) and E16: a return whose measured range falls outside [min_m, max_m], or
// beyond what the wire format can represent (context.max_wire_range_m, E9), is reported as no
// return: range 0, signal 0, reflectivity 0 (an Ouster sensor cannot tell these apart, [S24]);
// likewise a second return (dual profiles), which also goes when the first does.
// Place it after the noise effects and before quantization: the firmware compares the noisy range.
#include <algorithm>
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct RangeLimitsParameters {
  double min_m = 0.0;  // min_range_threshold_cm on current firmware: 0, 0.3 or 0.5 m ([S5])
  double max_m = 0.0;
};

// P(X <= x) for a standard normal X.
double normal_cdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

class RangeLimits final : public TabledEffect<RangeLimits, RangeLimitsParameters> {
 public:
  using P = RangeLimitsParameters;
  static constexpr std::string_view kName = "range_limits";
  static constexpr std::array<ParameterSpec<P>, 2> kSpecs{{
      {"min_m", &P::min_m, {0.0, 1000.0}, true},
      {"max_m", &P::max_m, {0.0, 10000.0}, true},
  }};

  explicit RangeLimits(const P& p) : TabledEffect(p) {}

  static void check(const P& p, const Location& at) {
    if (!(p.min_m < p.max_m)) {
      at.child("max_m").fail("must be greater than min_m (" + format_number(p.min_m) + "), got " +
                             format_number(p.max_m));
    }
  }

  bool adds_returns() const override { return false; }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    const float lower = static_cast<float>(params().min_m);
    const float upper = std::min(static_cast<float>(params().max_m), context.max_wire_range_m);
    float* __restrict range = measured.range_m.data();
    float* __restrict signal = measured.signal_photons.data();
    float* __restrict reflectivity = measured.reflectivity.data();
    const size_t n = measured.size();
    for (size_t b = 0; b < n; ++b) {  // a 0/1 factor instead of a branch: the loop vectorizes
      const float r = range[b];
      const float keep = (r == 0.0f || (r >= lower && r <= upper)) ? 1.0f : 0.0f;
      range[b] = r * keep;  // finite values: x * 0 = 0 (or -0, which every reader takes as 0)
      signal[b] *= keep;
      reflectivity[b] *= keep;
    }
    // The second return (dual profiles, E15) has the same window, and goes with the first: a pixel
    // whose strongest return the window removes reports none (what the firmware does then is not
    // documented; this keeps predict's detection the first return's alone).
    float* __restrict range2 = measured.range2_m.data();
    float* __restrict signal2 = measured.signal2_photons.data();
    float* __restrict reflectivity2 = measured.reflectivity2.data();
    for (size_t b = 0; b < n; ++b) {
      const float r = range2[b];
      const float keep = (range[b] != 0.0f && r >= lower && r <= upper) ? 1.0f : 0.0f;
      range2[b] = r * keep;
      signal2[b] *= keep;
      reflectivity2[b] *= keep;
    }
  }

  // P(min <= r + bias + noise <= max) under the noise predicted so far; the detected range is
  // that Gaussian truncated to the window, which the prediction records.
  void predict(const IdealReturn& ideal, const ColumnContext& context, Prediction& prediction) const override {
    const double lower = static_cast<double>(static_cast<float>(params().min_m));
    const double upper = static_cast<double>(std::min(static_cast<float>(params().max_m), context.max_wire_range_m));
    const auto inside = [&](double mean, double variance) {
      if (variance <= 0.0) return (mean >= lower && mean <= upper) ? 1.0 : 0.0;
      // Far inside the window (8.5 sigmas from each end) the difference below is exactly 1 (Phi(-8.5)
      // is below half an ulp of 1); the analysis predicts millions of pixels, and erfc, a square
      // root and divisions are its costliest steps: the test is made on squares.
      const double below = mean - lower, above = upper - mean;
      if (below > 0.0 && above > 0.0 && below * below > 72.25 * variance && above * above > 72.25 * variance) {
        return 1.0;
      }
      const double s = std::sqrt(variance);
      return normal_cdf((upper - mean) / s) - normal_cdf((lower - mean) / s);
    };
    const double mean = static_cast<double>(ideal.range_m) + prediction.bias_m;
    const double partner = prediction.partner_mix;  // E6, E8: a return from the edge partner's surface, a halo's
    // E2's tails: a tail_mix share of the pixel's own returns is wider, and crosses the window's
    // ends more often (a 28 cm tail at 1 m reaches below a 0.3 m minimum range).
    const double tail = std::clamp(prediction.tail_mix, 0.0, 1.0);
    double own = inside(mean, prediction.variance_m2);
    if (tail > 0.0) {
      own = (1.0 - tail) * own + tail * inside(mean, prediction.variance_m2 + prediction.tail_extra_variance_m2);
    }
    prediction.p_detect *=
        (1.0 - partner) * own + partner * inside(mean + prediction.partner_offset_m,
                                                 prediction.variance_m2 + prediction.partner_extra_variance_m2);
    prediction.window_min_m = std::max(prediction.window_min_m, lower);
    prediction.window_max_m = std::min(prediction.window_max_m, upper);
  }
};

}  // namespace

std::unique_ptr<Effect> make_range_limits(const nlohmann::json& params, const Location& at) {
  return RangeLimits::create(params, at);
}

EffectCard range_limits_card() {
  return {.catalogue = "E16", .note = "E16's near-range part (and E5's range part): returns beyond the range window"};
}

}  // namespace lidartwin::effects_detail
