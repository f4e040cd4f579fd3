// The counter-based generator: reproducible in any order and thread split, and well distributed.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/random/counter_rng.h"

using lidartwin::PixelKey;
using lidartwin::RandomStream;

namespace {
std::vector<PixelKey> pixel_grid() {
  std::vector<PixelKey> keys;
  for (uint64_t f = 0; f < 3; ++f)
    for (uint32_t c = 0; c < 64; ++c)
      for (uint32_t b = 0; b < 16; ++b) keys.push_back({f, c, b});
  return keys;
}
}  // namespace

TEST(Random, SameValuesInShuffledOrderAndAcrossThreads) {
  const auto keys = pixel_grid();
  std::vector<uint64_t> in_order(keys.size());
  for (size_t i = 0; i < keys.size(); ++i) in_order[i] = RandomStream(42, keys[i], 7).bits(3);

  std::vector<size_t> order(keys.size());
  std::iota(order.begin(), order.end(), 0);
  std::mt19937 shuffle_engine(12345);  // fixed seed: the order only needs to differ from 0..n
  std::shuffle(order.begin(), order.end(), shuffle_engine);
  std::vector<uint64_t> threaded(keys.size());
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (size_t j = static_cast<size_t>(t); j < order.size(); j += 4)
        threaded[order[j]] = RandomStream(42, keys[order[j]], 7).bits(3);
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(in_order, threaded);
}

TEST(Random, SeedEffectAndPixelEachChangeTheStream) {
  const RandomStream base(1, {0, 0, 0}, 0);
  EXPECT_NE(base.bits(0), RandomStream(2, {0, 0, 0}, 0).bits(0));
  EXPECT_NE(base.bits(0), RandomStream(1, {1, 0, 0}, 0).bits(0));
  EXPECT_NE(base.bits(0), RandomStream(1, {0, 1, 0}, 0).bits(0));
  EXPECT_NE(base.bits(0), RandomStream(1, {0, 0, 1}, 0).bits(0));
  EXPECT_NE(base.bits(0), RandomStream(1, {0, 0, 0}, 1).bits(0));
  EXPECT_NE(base.bits(0), base.bits(1));
}

TEST(Random, UniformAndNormalHaveTheRightMoments) {
  const int n = 200000;
  double sum = 0, sum2 = 0, nsum = 0, nsum2 = 0, nsum4 = 0;
  for (int i = 0; i < n; ++i) {
    const RandomStream s(9, {static_cast<uint64_t>(i / 1000), static_cast<uint32_t>(i % 1000), 0}, 3);
    const double u = s.uniform(0);
    ASSERT_GT(u, 0.0);
    ASSERT_LT(u, 1.0);
    sum += u;
    sum2 += u * u;
    const double z = s.normal(1);
    nsum += z;
    nsum2 += z * z;
    nsum4 += z * z * z * z;
  }
  EXPECT_NEAR(sum / n, 0.5, 0.005);
  EXPECT_NEAR(sum2 / n - 0.25, 1.0 / 12.0, 0.002);
  EXPECT_NEAR(nsum / n, 0.0, 0.01);
  EXPECT_NEAR(nsum2 / n, 1.0, 0.015);
  EXPECT_NEAR(nsum4 / n, 3.0, 0.1);  // Gaussian kurtosis, not just any unit-variance law
}
