// range_limits (E5 range part, E16): no-return rates and truncated moments against predict.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

TEST(RangeLimits, NoReturnRateAndTruncatedMomentsMatchPrediction) {
  const json sigma5cm = {
      {"name", "range_noise_linear"}, {"sigma0_m", 0.05}, {"sigma_max_m", 0.05}, {"range_max_m", 100.0}};
  const EffectChain chain =
      chain_of(json::array({sigma5cm, {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}}}));
  for (const float r : {0.2f, 0.28f, 0.3f, 0.35f, 50.0f, 99.95f, 100.0f, 100.06f, 100.3f}) {
    const Prediction p = chain.predict(surface(r), {});
    const Moments t = truncated(r, 0.05, 0.3, 100.0);  // independent of the effect's own window
    EXPECT_NEAR(p.p_detect, t.mass, 1e-6);
    EXPECT_NEAR(p.window_min_m, 0.3, 1e-6);
    EXPECT_NEAR(p.window_max_m, 100.0, 1e-6);
    expect_agreement(sample(chain, surface(r), 64 * 1024), t.mean, t.sd, p.p_detect, label("range_limits", r));
  }
}

TEST(RangeLimits, WireRangeLimitsToo) {
  // RNG15 profiles cannot represent more than 262.136 m (E9) even if the limits allow 300 m.
  ColumnContext context;
  context.max_wire_range_m = 262.136f;
  const EffectChain chain = chain_of(json::array({{{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 300.0}}}));
  EXPECT_EQ(chain.predict(surface(262.0f), context).p_detect, 1.0);
  EXPECT_EQ(chain.predict(surface(262.2f), context).p_detect, 0.0);
  EXPECT_EQ(sample(chain, surface(262.0f), 1024, context).detected, 1024u);
  EXPECT_EQ(sample(chain, surface(262.2f), 1024, context).detected, 0u);
  EXPECT_EQ(sample(chain, surface(0.29f), 1024, context).detected, 0u);
  EXPECT_EQ(chain.predict(IdealReturn{}, context).p_detect, 0.0);  // no hit, no return
}
