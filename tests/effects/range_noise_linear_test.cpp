// range_noise_linear (E1a, the paper's B0): its sigma line, and simulate against predict.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

TEST(RangeNoiseLinear, SigmaIsThePapersLine) {
  for (const auto& [effect, s0, smax, rmax] :
       {std::tuple{kLinearOs0, 0.01, 0.10, 45.0}, std::tuple{kLinearOs1, 0.01, 0.15, 100.0}}) {
    const EffectChain chain = chain_of(json::array({effect}));
    for (const double r : {0.3, 1.0, 10.0, 22.5, 45.0, 100.0, 150.0}) {  // 150: extrapolated beyond r_max
      EXPECT_NEAR(predicted_sd(chain, static_cast<float>(r)),
                  s0 + (smax - s0) * static_cast<double>(static_cast<float>(r)) / rmax, 1e-9)
          << "r = " << r;
    }
  }
  // lidar-physics.md section 0: at 10 m B0 gives 2.4 cm (OS1) and 3.0 cm (OS0).
  EXPECT_NEAR(predicted_sd(chain_of(json::array({kLinearOs1})), 10.0f), 0.024, 1e-9);
  EXPECT_NEAR(predicted_sd(chain_of(json::array({kLinearOs0})), 10.0f), 0.030, 1e-9);
}

TEST(RangeNoiseLinear, SamplesMatchPrediction) {
  const EffectChain chain = chain_of(json::array({kLinearOs1}));
  for (const float r : {0.5f, 5.0f, 20.0f, 45.0f, 80.0f, 120.0f}) {
    const Prediction p = chain.predict(surface(r), {});
    expect_agreement(sample(chain, surface(r), 64 * 1024), static_cast<double>(r) + p.bias_m, std::sqrt(p.variance_m2),
                     p.p_detect, label("range_noise_linear", r));
  }
}
