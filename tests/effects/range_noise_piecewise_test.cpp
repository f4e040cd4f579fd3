// range_noise_piecewise (E1b, the datasheet's Table I): knots, the table, simulate against predict.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

TEST(RangeNoisePiecewise, PassesThroughKnotsAndIsConstantBeyond) {
  for (const json& knots : {kKnotsOs0, kKnotsOs1}) {
    const EffectChain chain = chain_of(json::array({piecewise(knots)}));
    for (const auto& knot : knots) {
      EXPECT_NEAR(predicted_sd(chain, knot[0].get<float>()), knot[1].get<double>(), 1e-7) << knot.dump();
    }
    EXPECT_DOUBLE_EQ(predicted_sd(chain, 0.1f), knots.front()[1].get<double>());
    EXPECT_DOUBLE_EQ(predicted_sd(chain, 400.0f), knots.back()[1].get<double>());
    // Linear between knots: a ramp's midpoint is the mean of its ends.
    const double r = 0.5 * (knots[1][0].get<double>() + knots[2][0].get<double>());
    EXPECT_NEAR(predicted_sd(chain, static_cast<float>(r)),
                0.5 * (knots[1][1].get<double>() + knots[2][1].get<double>()), 1e-6);
  }
}

TEST(RangeNoisePiecewise, MatchesTableIOfThePaper) {
  // Tejero et al., Table I: precision (1 sigma) of a 10 % Lambertian target per range interval.
  struct Interval {
    double from_m, to_m, sigma_m;
  };
  const std::vector<Interval> os0{{0.3, 1, 0.02}, {1, 10, 0.01}, {10, 15, 0.015}, {15, 45, 0.05}};
  const std::vector<Interval> os1{{0.3, 1, 0.007}, {1, 20, 0.01}, {20, 50, 0.02}, {50, 100, 0.05}};
  for (const auto& [knots, table] : {std::pair{kKnotsOs0, os0}, std::pair{kKnotsOs1, os1}}) {
    const EffectChain chain = chain_of(json::array({piecewise(knots)}));
    for (const Interval& bin : table) {
      // Inside the interval, away from the +-2 % ramps at its edges, sigma is the table's value.
      const double lo = bin.from_m * 1.025, hi = bin.to_m / 1.025;
      for (int i = 0; i <= 20; ++i) {
        const double r = bin.from_m <= 0.3 ? 0.3 + (hi - 0.3) * i / 20.0 : lo + (hi - lo) * i / 20.0;
        EXPECT_NEAR(predicted_sd(chain, static_cast<float>(r)), bin.sigma_m, 1e-9) << "r = " << r;
      }
    }
  }
}

TEST(RangeNoisePiecewise, SamplesMatchPrediction) {
  const EffectChain chain = chain_of(json::array({piecewise(kKnotsOs0)}));
  for (const float r : {0.5f, 1.0f, 5.0f, 12.0f, 15.0f, 30.0f, 60.0f}) {
    const Prediction p = chain.predict(surface(r), {});
    expect_agreement(sample(chain, surface(r), 64 * 1024), static_cast<double>(r) + p.bias_m, std::sqrt(p.variance_m2),
                     p.p_detect, label("range_noise_piecewise", r));
  }
}

// The segment search is a table and a count of comparisons; it must give the sigma of a plain
// search from the first knot, at knots, next to them, and beyond both ends, whatever the spacing
// (several knots within one eighth of an octave, knots below 2^-6 m and above 2^10 m). Equal to
// rounding: the library may fuse the multiply-add where this test does not.
TEST(RangeNoisePiecewise, SigmaIsExactlyThatOfAPlainSearch) {
  const json close_knots = json::parse(
      "[[0.001, 0.5], [0.004, 0.2], [0.01, 0.3], [1.0, 0.01], [1.01, 0.02], [1.02, 0.015], [1.03, 0.04],"
      " [1.04, 0.02], [300, 0.1], [2000, 0.3], [9000, 0.2]]");
  for (const json& knots : {kKnotsOs0, kKnotsOs1, close_knots}) {
    const auto plain_sigma = [&knots](float range_m) {
      const double r = static_cast<double>(range_m);
      const size_t n = knots.size();
      const auto at = [&knots](size_t k, int c) { return knots[k][c].get<double>(); };
      if (r <= at(0, 0)) return at(0, 1);
      if (r >= at(n - 1, 0)) return at(n - 1, 1);
      size_t k = 0;
      while (k + 2 < n && r > at(k + 1, 0)) ++k;
      const double slope = (at(k + 1, 1) - at(k, 1)) / (at(k + 1, 0) - at(k, 0));
      return at(k, 1) + slope * (r - at(k, 0));
    };
    std::vector<float> ranges{0.0001f, 0.3f, 50.0f, 5000.0f, 20000.0f};
    for (const auto& knot : knots) {
      const float r = knot[0].get<float>();
      ranges.insert(ranges.end(), {r, std::nextafter(r, 0.0f), std::nextafter(r, 1e9f), r * 1.001f, r * 0.999f});
    }
    for (float r = 0.01f; r < 12000.0f; r *= 1.0137f) ranges.push_back(r);
    const EffectChain chain = chain_of(json::array({piecewise(knots)}));
    for (const float r : ranges) {
      const double sigma = plain_sigma(r);
      EXPECT_NEAR(chain.predict(surface(r), {}).variance_m2, sigma * sigma, 1e-12 * sigma * sigma)
          << "r = " << r << ", knots " << knots.dump();
    }
  }
}
