// fog (E13): two-way extinction of SIGNAL, detection following it, and soft-target returns before
// the surface with the extinction-weighted range distribution; simulate against predict, bounds too.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

json fog(double alpha, double soft_probability = 0.0, double soft_signal = 5.0) {
  return {{"name", "fog"},
          {"attenuation_per_m", alpha},
          {"soft_return_probability", soft_probability},
          {"soft_signal_photons", soft_signal},
          {"max_range_m", 80.0}};
}

TEST(Fog, SignalFallsByTheTwoWayExtinction) {
  const EffectChain clear = chain_of(json::array({{{"name", "radiometry"}}}));
  for (const double alpha : {0.0, 0.06, 1.0}) {
    const EffectChain foggy = chain_of(json::array({{{"name", "radiometry"}}, fog(alpha)}));
    for (const float r : {2.0f, 10.0f, 30.0f}) {
      const IdealReturn wall = surface(r, 0.4f);
      const double tau = std::exp(-2.0 * alpha * static_cast<double>(r));
      EXPECT_NEAR(foggy.predict(wall, {}).signal_photons, tau * clear.predict(wall, {}).signal_photons,
                  1e-9 * clear.predict(wall, {}).signal_photons);
      std::vector<Measurement> a(kBeams), b(kBeams);
      clear.simulate(std::vector<IdealReturn>(kBeams, wall), {}, a);
      foggy.simulate(std::vector<IdealReturn>(kBeams, wall), {}, b);
      const auto clear_signal = static_cast<double>(a[0].signal_photons);
      const auto clear_reflectivity = static_cast<double>(a[0].reflectivity);
      EXPECT_NEAR(b[0].signal_photons, tau * clear_signal, 1e-5 * clear_signal + 1e-30) << alpha;
      EXPECT_NEAR(b[0].reflectivity, tau * clear_reflectivity, 1e-5 * clear_reflectivity + 1e-30) << alpha;
      EXPECT_EQ(b[0].range_m, a[0].range_m);
    }
  }
}

TEST(Fog, DetectionFollowsTheExtinction) {
  for (const double alpha : {0.0, 0.01, 0.03}) {
    const EffectChain chain =
        chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1, fog(alpha), {{"name", "dropout"}}}));
    const IdealReturn target = surface(30.0f, 0.2f);
    const Prediction p = chain.predict(target, {});
    expect_agreement(sample(chain, target, 64 * 1024), 30.0 + p.bias_m, std::sqrt(p.variance_m2), p.p_detect,
                     "fog alpha " + std::to_string(alpha));
  }
}

// Soft returns: their rates by strength against the surface (as the window's near returns), and
// their ranges distributed as exp(-2 alpha r') up to the surface (a Kolmogorov-Smirnov test against
// that distribution's CDF, written here from the formula).
TEST(Fog, SoftReturnsComeBeforeTheSurfaceAtTheirRate) {
  const double alpha = 0.05, soft_signal = 20.0;
  const EffectChain radiometry = chain_of(json::array({{{"name", "radiometry"}}}));
  const IdealReturn strong = surface(6.0f, 0.8f), weak = surface(40.0f, 0.1f), sky;
  ASSERT_GT(radiometry.predict(strong, {}).signal_photons * std::exp(-2.0 * alpha * 6.0), soft_signal);
  ASSERT_LT(radiometry.predict(weak, {}).signal_photons, soft_signal);
  for (const double probability : {0.0, 0.05, 1.0}) {
    const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}}, fog(alpha, probability, soft_signal)}));
    for (const IdealReturn& in : {strong, weak, sky}) {
      const Prediction p = chain.predict(in, {});
      const double end = in.hit() ? static_cast<double>(in.range_m) : 80.0;
      size_t n = 0, detected = 0, soft_first = 0, second = 0;
      std::vector<double> soft_ranges;
      std::vector<Measurement> out(kBeams);
      const std::vector<IdealReturn> column(kBeams, in);
      for (uint32_t c = 0; n < 32 * 1024; ++c) {
        ColumnContext context;
        context.column = c;
        chain.simulate(column, context, out);
        for (const Measurement& m : out) {
          ++n;
          detected += m.range_m != 0.0f;
          second += m.range2_m != 0.0f;
          const bool first_is_soft = m.range_m != 0.0f && m.signal_photons == static_cast<float>(soft_signal);
          soft_first += first_is_soft;
          if (first_is_soft) soft_ranges.push_back(m.range_m);
          if (m.range2_m != 0.0f && m.signal2_photons == static_cast<float>(soft_signal)) {
            soft_ranges.push_back(m.range2_m);
          }
        }
      }
      const auto rate = [n](size_t k) { return static_cast<double>(k) / static_cast<double>(n); };
      const auto se = [n](double q) { return std::sqrt(std::max(q * (1.0 - q), 1.0 / static_cast<double>(n)) / n); };
      const double expected_first = in.hit() ? p.outlier_mix : p.p_detect;
      std::sort(soft_ranges.begin(), soft_ranges.end());
      double ks = 0.0;
      const auto k = static_cast<double>(soft_ranges.size());
      for (size_t i = 0; i < soft_ranges.size(); ++i) {
        const double cdf = -std::expm1(-2.0 * alpha * soft_ranges[i]) / -std::expm1(-2.0 * alpha * end);
        ks = std::max({ks, std::abs(cdf - static_cast<double>(i) / k), std::abs(cdf - static_cast<double>(i + 1) / k)});
      }
      std::printf(
          "  p %.2f end %4.0f m: detected %.4f vs %.4f, soft first %.4f vs %.4f, second %.4f vs %.4f, KS %.4f\n",
          probability, end, rate(detected), p.p_detect, rate(soft_first), expected_first, rate(second), p.p_second, ks);
      EXPECT_NEAR(rate(detected), p.p_detect, 5.0 * se(p.p_detect));
      EXPECT_NEAR(rate(soft_first), expected_first, 5.0 * se(expected_first));
      EXPECT_NEAR(rate(second), in.hit() ? p.p_second : 0.0, 5.0 * se(p.p_second));
      if (!soft_ranges.empty()) {
        EXPECT_LT(ks, 1.63 / std::sqrt(k)) << "soft-return ranges against exp(-2 alpha r) on (0, " << end << "]";
        EXPECT_LE(soft_ranges.back(), end + 1e-3);
      }
    }
  }
}

}  // namespace
