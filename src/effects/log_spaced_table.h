#pragma once
// A smooth positive function of range, tabulated once so a pixel costs a lookup instead of pow()
// and exp(). Knots are the floats whose bit patterns share their top bits (exponent and the top
// 8 mantissa bits): 256 knots per octave from 2^-6 m to 2^10 m, 16 KB. Within a knot interval
// a float's low mantissa bits are linear in its value, so interpolating on them is exact linear
// interpolation in r; the relative spacing of 1/256 keeps the error near 1e-5 for r^-2 laws.
#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

namespace lidartwin::effects_detail {

class LogSpacedTable {
 public:
  static constexpr float kMinRange = 0x1.0p-6f;
  static constexpr float kMaxRange = 0x1.0p10f;

  template <class F>  // f: double range_m -> double
  explicit LogSpacedTable(F f) {
    const uint32_t knots = ((bits(kMaxRange) - bits(kMinRange)) >> kFractionBits) + 1;
    values_.resize(knots + 1);  // +1: interpolation at kMaxRange reads one past its knot
    for (uint32_t k = 0; k < values_.size(); ++k) {
      const float r = std::bit_cast<float>(bits(kMinRange) + (k << kFractionBits));
      values_[k] = static_cast<float>(f(static_cast<double>(r)));
    }
  }

  // Ranges outside [kMinRange, kMaxRange] take the end values. The clamp is done on the bit
  // patterns (positive floats order like their bits; negatives and NaN clamp to an end): integer
  // min/max vectorize where float ones would need -ffinite-math-only, so callers' loops over a
  // column vectorize, the lookups becoming gathers.
  float operator()(float range_m) const {
    const int32_t clamped = std::min(std::max(std::bit_cast<int32_t>(range_m), kMinBits), kMaxBits);
    const auto offset = static_cast<uint32_t>(clamped - kMinBits);
    const uint32_t k = offset >> kFractionBits;
    const float t = static_cast<float>(offset & kFractionMask) * (1.0f / static_cast<float>(kFractionMask + 1));
    const float* v = values_.data();
    return v[k] + t * (v[k + 1] - v[k]);
  }

 private:
  static constexpr uint32_t kFractionBits = 23 - 8;  // float mantissa bits below the top 8
  static constexpr uint32_t kFractionMask = (1u << kFractionBits) - 1;
  static constexpr uint32_t bits(float x) { return std::bit_cast<uint32_t>(x); }
  static constexpr int32_t kMinBits = std::bit_cast<int32_t>(kMinRange);
  static constexpr int32_t kMaxBits = std::bit_cast<int32_t>(kMaxRange);

  std::vector<float> values_;
};

}  // namespace lidartwin::effects_detail
