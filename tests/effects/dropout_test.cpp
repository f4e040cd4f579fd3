// dropout (E5): its no-return rate against predict, and its place in a chain.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

TEST(Dropout, NoReturnRateMatchesPrediction) {
  const EffectChain chain = chain_of(
      json::array({{{"name", "radiometry"}}, kLinearOs1, {{"name", "dropout"}, {"ambient_coefficient", 0.2}}}));
  for (const float r : {10.0f, 30.0f, 40.0f, 50.0f, 60.0f, 80.0f}) {
    const Prediction p = chain.predict(surface(r, 0.1f), {});
    expect_agreement(sample(chain, surface(r, 0.1f), 64 * 1024), static_cast<double>(r) + p.bias_m,
                     std::sqrt(p.variance_m2), p.p_detect, label("dropout rho 0.1", r));
  }
  // The Gen1 OS1 range spec points (40 m at 10 %, 120 m at 80 %) are detected about 90 % of the time.
  const EffectChain defaults = chain_of(json::array({{{"name", "radiometry"}}, {{"name", "dropout"}}}));
  EXPECT_NEAR(defaults.predict(surface(40.0f, 0.1f), {}).p_detect, 0.92, 0.03);
  EXPECT_NEAR(defaults.predict(surface(120.0f, 0.8f), {}).p_detect, 0.90, 0.03);
}

TEST(Dropout, NeedsRadiometryEarlierInTheChain) {
  try {
    EffectChain::from_json(json::array({{{"name", "dropout"}}, {{"name", "radiometry"}}}),
                           Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/0: dropout needs radiometry earlier in the chain");
  }
}
