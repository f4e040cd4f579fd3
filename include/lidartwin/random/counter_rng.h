#pragma once
// Counter-based random numbers: every draw is a pure function of
// (seed, frame, column, beam, effect, draw), so noise never depends on threads, batching or the
// order pixels are visited (DESIGN.md "Choices already made"; pbrt's IndependentSampler idea).
#include <cmath>
#include <cstdint>

namespace lidartwin {

struct PixelKey {
  uint64_t frame = 0;
  uint32_t column = 0;
  uint32_t beam = 0;
  friend bool operator==(const PixelKey&, const PixelKey&) = default;
};

namespace rng_detail {
// SplitMix64's finalizer (Stafford variant 13): a bijective 64-bit mixer with full avalanche.
constexpr uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// (0, 1) from the top 53 bits, and (-1, 1) from the same bits.
constexpr double unit(uint64_t bits) { return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53; }
constexpr double signed_unit(uint64_t bits) { return 2.0 * unit(bits) - 1.0; }

// Layer edges x[0..256] (x[0] = V/f(R) is the base strip's width, x[1] = R, x[256] = 0) and the
// fast-path ratios x[i+1]/x[i], for f(x) = exp(-x^2/2) (Doornik 2005, "An improved ziggurat
// method to generate normal random samples", constants for 256 layers).
struct ZigguratTable {
  static constexpr int kLayers = 256;
  static constexpr double kR = 3.6541528853610088;
  static constexpr double kV = 0.00492867323399;
  double x[kLayers + 1];
  double ratio[kLayers];
};

inline const ZigguratTable& ziggurat_table() {
  static const ZigguratTable table = [] {
    ZigguratTable t{};
    constexpr int n = ZigguratTable::kLayers;
    double f = std::exp(-0.5 * ZigguratTable::kR * ZigguratTable::kR);
    t.x[0] = ZigguratTable::kV / f;
    t.x[1] = ZigguratTable::kR;
    t.x[n] = 0.0;
    for (int i = 2; i < n; ++i) {
      t.x[i] = std::sqrt(-2.0 * std::log(ZigguratTable::kV / t.x[i - 1] + f));
      f = std::exp(-0.5 * t.x[i] * t.x[i]);
    }
    for (int i = 0; i < n; ++i) t.ratio[i] = t.x[i + 1] / t.x[i];
    return t;
  }();
  return table;
}

// The ziggurat's rejection part, entered with the first draw `b` that missed the fast path.
inline double ziggurat_slow(uint64_t b, uint64_t extra_seed) {
  const auto& t = ziggurat_table();
  uint64_t state = extra_seed;
  auto next = [&state] { return mix64(state += 0x9E3779B97F4A7C15ULL); };
  for (;;) {
    const double u = signed_unit(b);
    const uint32_t i = static_cast<uint32_t>(b & 0xFF);
    if (std::abs(u) < t.ratio[i]) return u * t.x[i];
    if (i == 0) {  // the tail beyond R (Marsaglia 1964)
      double x = 0.0;
      double y = 0.0;
      do {
        x = std::log(unit(next())) / ZigguratTable::kR;
        y = std::log(unit(next()));
      } while (-2.0 * y < x * x);
      return u < 0.0 ? x - ZigguratTable::kR : ZigguratTable::kR - x;
    }
    // Wedge: accept if a uniform height in layer i lies under the density at x.
    const double x = u * t.x[i];
    const double f0 = std::exp(-0.5 * (t.x[i] * t.x[i] - x * x));
    const double f1 = std::exp(-0.5 * (t.x[i + 1] * t.x[i + 1] - x * x));
    if (f1 + unit(next()) * (f0 - f1) < 1.0) return x;
    b = next();
  }
}
}  // namespace rng_detail

// The stream of one (seed, pixel, effect). Cheap to build; draw(i) is independent of any other call.
class RandomStream {
 public:
  constexpr RandomStream(uint64_t seed, const PixelKey& pixel, uint32_t effect_id)
      : key_(pixel_key(effect_key(seed, pixel.frame, effect_id), pixel.column, pixel.beam)) {}

  // The key in two stages, the pixel last, so ColumnStreams mixes the rest once per column and a
  // pixel's stream costs one multiply.
  static constexpr uint64_t effect_key(uint64_t seed, uint64_t frame, uint32_t effect_id) {
    using rng_detail::mix64;
    const uint64_t k = mix64(mix64(seed ^ 0x6C69646172747769ULL) ^ frame);  // "lidartwi"
    return mix64(k ^ (static_cast<uint64_t>(effect_id) * 0x9E3779B97F4A7C15ULL));
  }
  // One multiply, not a full mix: bits() mixes key + draw fully anyway, and an odd multiplier is a
  // bijection, so distinct pixels keep distinct keys. (A second mix64 here cost about a third of
  // a Gaussian draw: tests/bench/effects_bench.cpp.)
  static constexpr uint64_t pixel_key(uint64_t effect_key, uint32_t column, uint32_t beam) {
    return effect_key ^ (((static_cast<uint64_t>(column) << 32) | beam) * 0xD1B54A32D192ED03ULL);
  }

  constexpr uint64_t bits(uint32_t draw) const {
    return rng_detail::mix64(key_ + (static_cast<uint64_t>(draw) + 1) * 0x9E3779B97F4A7C15ULL);
  }
  // Uniform in (0, 1): never 0, so log(u) is finite.
  constexpr double uniform(uint32_t draw) const { return rng_detail::unit(bits(draw)); }
  // Standard normal from draws (2*pair, 2*pair+1) by Box-Muller.
  double normal(uint32_t pair) const {
    const double u1 = uniform(2 * pair);
    const double u2 = uniform(2 * pair + 1);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }
  // Standard normal by the ziggurat method (Marsaglia & Tsang 2000, in Doornik's 2005 ZIGNOR
  // form, 256 layers): exact like normal(pair), several times faster (no log, sqrt or cos on
  // 99.3 % of draws; tests/bench/effects_bench.cpp), and a different value for the same pair.
  // Uses draw 2*pair (layer from the low 8 bits, position from the top 53); the rare slow path
  // continues with a SplitMix64 sequence seeded by draw 2*pair+1, so the value is still a pure
  // function of the counter.
  double normal_ziggurat(uint32_t pair) const {
    const auto& table = rng_detail::ziggurat_table();
    const uint64_t b = bits(2 * pair);
    const double u = rng_detail::signed_unit(b);
    const uint32_t layer = static_cast<uint32_t>(b & 0xFF);
    if (std::abs(u) < table.ratio[layer]) return u * table.x[layer];
    return rng_detail::ziggurat_slow(b, bits(2 * pair + 1));
  }

 private:
  friend class ColumnStreams;
  struct FromKey {};
  constexpr RandomStream(FromKey, uint64_t key) : key_(key) {}

  uint64_t key_ = 0;
};

// The streams of one (seed, frame, column, effect) for every beam of a column: the shared part of
// the key is mixed once, so a pixel's stream costs one multiply.
// streams(beam) == RandomStream(seed, {frame, column, beam}, effect_id), bit for bit.
class ColumnStreams {
 public:
  constexpr ColumnStreams(uint64_t seed, uint64_t frame, uint32_t column, uint32_t effect_id)
      : effect_key_(RandomStream::effect_key(seed, frame, effect_id)), column_(column) {}
  constexpr RandomStream operator()(uint32_t beam) const {
    return RandomStream(RandomStream::FromKey{}, RandomStream::pixel_key(effect_key_, column_, beam));
  }

 private:
  uint64_t effect_key_;
  uint32_t column_;
};

}  // namespace lidartwin
