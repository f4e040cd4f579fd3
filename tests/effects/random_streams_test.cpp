// The random streams effects draw from: per-column streams equal per-pixel ones, the ziggurat is N(0, 1).
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

TEST(EffectsRandom, ColumnStreamsEqualPerPixelStreams) {
  const lidartwin::ColumnStreams streams(77, 5, 1023, 9);
  for (uint32_t beam = 0; beam < 128; ++beam) {
    EXPECT_EQ(streams(beam).bits(0), lidartwin::RandomStream(77, {5, 1023, beam}, 9).bits(0));
    EXPECT_EQ(streams(beam).bits(7), lidartwin::RandomStream(77, {5, 1023, beam}, 9).bits(7));
  }
}

TEST(EffectsRandom, ZigguratIsStandardNormal) {
  const int n = 1 << 21;
  std::vector<double> z(n);
  double sum = 0, sum2 = 0, sum4 = 0;
  int beyond3 = 0, beyond4 = 0;
  for (int i = 0; i < n; ++i) {
    z[i] = lidartwin::RandomStream(3, {static_cast<uint64_t>(i >> 10), static_cast<uint32_t>(i & 1023), 1}, 4)
               .normal_ziggurat(static_cast<uint32_t>(i % 3));
    sum += z[i];
    sum2 += z[i] * z[i];
    sum4 += z[i] * z[i] * z[i] * z[i];
    beyond3 += std::abs(z[i]) > 3.0;
    beyond4 += std::abs(z[i]) > 4.0;  // the tail beyond R = 3.654 comes from the slow path
  }
  EXPECT_NEAR(sum / n, 0.0, 5.0 / std::sqrt(n));
  EXPECT_NEAR(sum2 / n, 1.0, 5.0 * std::sqrt(2.0 / n));
  EXPECT_NEAR(sum4 / n, 3.0, 5.0 * std::sqrt(96.0 / n));
  const double p3 = 2.0 * normal_cdf(-3.0), p4 = 2.0 * normal_cdf(-4.0);
  EXPECT_NEAR(beyond3, n * p3, 5.0 * std::sqrt(n * p3));
  EXPECT_NEAR(beyond4, n * p4, 5.0 * std::sqrt(n * p4));
  // Kolmogorov-Smirnov against Phi: critical value at alpha = 0.001 is 1.95 / sqrt(n).
  std::sort(z.begin(), z.end());
  double d = 0.0;
  for (int i = 0; i < n; ++i) {
    const double f = normal_cdf(z[i]);
    d = std::max({d, f - static_cast<double>(i) / n, static_cast<double>(i + 1) / n - f});
  }
  std::printf("  ziggurat: mean %.2e var %.5f kurtosis %.4f P(|z|>4) %.2e vs %.2e, KS D %.2e (crit %.2e)\n", sum / n,
              sum2 / n, sum4 / n, static_cast<double>(beyond4) / n, p4, d, 1.95 / std::sqrt(n));
  EXPECT_LT(d, 1.95 / std::sqrt(static_cast<double>(n)));
}
