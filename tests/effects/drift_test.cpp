// drift (E12): a common-mode offset that decays from warm-up and grows linearly, by column time.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

const json kDrift = {
    {"name", "drift"}, {"offset_m", 0.01}, {"warmup_offset_m", 0.04}, {"warmup_time_s", 60}, {"rate_m_per_h", 0.036}};

TEST(Drift, OffsetFollowsWarmUpAndRate) {
  const EffectChain chain = chain_of(json::array({kDrift}));
  for (const double t : {0.0, 60.0, 600.0, 3600.0}) {
    ColumnContext context;
    context.time_s = t;
    const double expected = 0.01 + 0.04 * std::exp(-t / 60.0) + 0.036 * t / 3600.0;
    EXPECT_NEAR(chain.predict(surface(12.0f), context).bias_m, expected, 1e-12) << t;
    std::vector<Measurement> out(kBeams);
    chain.simulate(std::vector<IdealReturn>(kBeams, surface(12.0f)), context, out);
    for (const Measurement& m : out) EXPECT_NEAR(static_cast<double>(m.range_m), 12.0 + expected, 1e-5) << t;
  }
}

TEST(Drift, SamplesMatchPredictionWithNoise) {
  const EffectChain chain = chain_of(json::array({kLinearOs1, kDrift}));
  ColumnContext context;
  context.time_s = 30.0;
  const Prediction p = chain.predict(surface(20.0f), context);
  expect_agreement(sample(chain, surface(20.0f), 64 * 1024, context), 20.0 + p.bias_m, std::sqrt(p.variance_m2),
                   p.p_detect, label("drift", 20.0f));
}

}  // namespace
