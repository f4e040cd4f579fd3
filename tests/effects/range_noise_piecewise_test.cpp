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
