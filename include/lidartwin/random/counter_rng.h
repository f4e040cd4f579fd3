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
}  // namespace rng_detail

// The stream of one (seed, pixel, effect). Cheap to build; draw(i) is independent of any other call.
class RandomStream {
 public:
  constexpr RandomStream(uint64_t seed, const PixelKey& pixel, uint32_t effect_id) {
    using rng_detail::mix64;
    uint64_t k = mix64(seed ^ 0x6C69646172747769ULL);  // "lidartwi"
    k = mix64(k ^ pixel.frame);
    k = mix64(k ^ ((static_cast<uint64_t>(pixel.column) << 32) | pixel.beam));
    key_ = mix64(k ^ (static_cast<uint64_t>(effect_id) * 0x9E3779B97F4A7C15ULL));
  }

  constexpr uint64_t bits(uint32_t draw) const {
    return rng_detail::mix64(key_ + (static_cast<uint64_t>(draw) + 1) * 0x9E3779B97F4A7C15ULL);
  }
  // Uniform in (0, 1): never 0, so log(u) is finite.
  constexpr double uniform(uint32_t draw) const {
    return (static_cast<double>(bits(draw) >> 11) + 0.5) * 0x1.0p-53;
  }
  // Standard normal from draws (2*pair, 2*pair+1) by Box-Muller.
  double normal(uint32_t pair) const {
    const double u1 = uniform(2 * pair);
    const double u2 = uniform(2 * pair + 1);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  uint64_t key_ = 0;
};

}  // namespace lidartwin
