// signal_precision (E2) and range_walk (E3): effects of the expected SIGNAL that radiometry makes.
// Fewer photons widen the spread as k sqrt(S + B) / S; more photons shorten the range by walk per
// decade; simulate draws what predict says.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

const json kRadiometry = {{"name", "radiometry"}};
const json kPrecision = {{"name", "signal_precision"}, {"k_m", 0.3}, {"floor_m", 0.002}};
const json kWalk = {{"name", "range_walk"}, {"walk_m", 0.01}, {"reference_photons", 50}, {"retro_offset_m", -0.03}};

TEST(SignalPrecision, SpreadFollowsThePhotonCount) {
  const EffectChain chain = chain_of(json::array({kRadiometry, kPrecision}));
  for (const float r : {3.0f, 10.0f, 40.0f}) {
    for (const float rho : {0.05f, 0.5f}) {
      const Prediction p = chain.predict(surface(r, rho), {});
      const double s = std::max(p.signal_photons, 1.0);
      const double expected = 0.002 * 0.002 + 0.09 * (s + p.near_ir_photons) / (s * s);
      EXPECT_NEAR(p.variance_m2, expected, 1e-12) << r << " m, rho " << rho;
    }
  }
  // A darker target at the same range is noisier.
  EXPECT_GT(chain.predict(surface(20.0f, 0.05f), {}).variance_m2, chain.predict(surface(20.0f, 0.5f), {}).variance_m2);
}

TEST(SignalPrecision, SamplesMatchPrediction) {
  const EffectChain chain = chain_of(json::array({kRadiometry, kPrecision}));
  for (const float r : {5.0f, 30.0f}) {
    for (const float rho : {0.05f, 0.8f}) {
      const Prediction p = chain.predict(surface(r, rho), {});
      expect_agreement(sample(chain, surface(r, rho), 64 * 1024), static_cast<double>(r) + p.bias_m,
                       std::sqrt(p.variance_m2), p.p_detect, label("signal_precision", r));
    }
  }
}

TEST(RangeWalk, BrightReturnsReadShortByWalkPerDecade) {
  const EffectChain chain = chain_of(json::array({kRadiometry, kWalk}));
  const Prediction near = chain.predict(surface(5.0f, 0.9f), {});
  ASSERT_GT(near.signal_photons, 500.0);
  EXPECT_NEAR(near.bias_m, -0.01 * std::log10(near.signal_photons / 50.0), 1e-12);
  const Prediction dim = chain.predict(surface(60.0f, 0.02f), {});
  ASSERT_LT(dim.signal_photons, 50.0);
  EXPECT_EQ(dim.bias_m, 0.0);  // below the reference: no walk
  IdealReturn retro = surface(20.0f, 0.5f);
  retro.retroreflective = 1;
  const Prediction r = chain.predict(retro, {});
  EXPECT_NEAR(r.bias_m, -0.01 * std::log10(std::max(r.signal_photons, 50.0) / 50.0) - 0.03, 1e-12);
}

TEST(RangeWalk, SamplesMatchPrediction) {
  const EffectChain chain = chain_of(json::array({kRadiometry, kLinearOs1, kWalk}));
  for (const float r : {2.0f, 15.0f}) {
    const Prediction p = chain.predict(surface(r, 0.9f), {});
    expect_agreement(sample(chain, surface(r, 0.9f), 64 * 1024), static_cast<double>(r) + p.bias_m,
                     std::sqrt(p.variance_m2), p.p_detect, label("range_walk", r));
  }
}

TEST(SignalEffects, NeedRadiometryFirst) {
  EXPECT_THROW(chain_of(json::array({kPrecision})), InputError);
  EXPECT_THROW(chain_of(json::array({kWalk, kRadiometry})), InputError);
}

}  // namespace
