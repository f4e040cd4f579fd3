// incidence (E4): the footprint's spread and bias grow as r * tan(theta) (or, saturating, more slowly
// towards grazing), and simulate draws what predict says.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

const json kIncidence = {{"name", "incidence"}, {"divergence_rad", 0.002}, {"bias_factor", 0.5}};

TEST(Incidence, SpreadAndBiasFollowRangeTimesTanTheta) {
  const EffectChain chain = chain_of(json::array({kIncidence}));
  for (const double degrees : {0.0, 30.0, 60.0, 75.0}) {
    const double theta = degrees * 3.141592653589793 / 180.0;
    const auto c = static_cast<float>(std::cos(theta));
    const Prediction p = chain.predict(surface(20.0f, 0.5f, c), {});
    const double footprint = 20.0 * std::tan(std::acos(static_cast<double>(c))) * 0.002;
    // tan(theta) is taken in float (the cosine is one): float's relative precision, not double's.
    EXPECT_NEAR(std::sqrt(p.variance_m2), footprint / 2.3548200450309493, 1e-6 * footprint) << degrees;
    EXPECT_NEAR(p.bias_m, 0.5 * footprint, 1e-6 * footprint) << degrees;
  }
  // OS1-64 divergence 0.13 degrees at 10 m and 75 degrees: lidar-physics.md's 3.6 cm footprint (FWHM).
  const EffectChain os1 = chain_of(json::array({{{"name", "incidence"}}}));
  const Prediction p =
      os1.predict(surface(10.0f, 0.5f, static_cast<float>(std::cos(75.0 * 3.141592653589793 / 180))), {});
  EXPECT_NEAR(std::sqrt(p.variance_m2) * 2.3548200450309493, 0.0847, 0.001);  // 10 * tan 75 * 0.00227
}

TEST(Incidence, SamplesMatchPrediction) {
  const EffectChain chain = chain_of(json::array({kIncidence}));
  for (const float c : {0.9f, 0.5f, 0.2f}) {
    const IdealReturn in = surface(15.0f, 0.5f, c);
    const Prediction p = chain.predict(in, {});
    expect_agreement(sample(chain, in, 64 * 1024), 15.0 + p.bias_m, std::sqrt(p.variance_m2), p.p_detect,
                     label("incidence", c));
  }
}

}  // namespace

// saturation s: the footprint's depth grows as tan(theta) / (1 + s tan(theta)), about the
// footprint law at small angles, at most r * gamma / s towards grazing; simulate draws what predict
// says with it too.
TEST(Incidence, ASaturatingFootprintBendsTanThetaOverAndSamplesMatch) {
  json saturating = kIncidence;
  saturating["saturation"] = 0.25;
  const EffectChain chain = chain_of(json::array({saturating}));
  const EffectChain footprint_law = chain_of(json::array({kIncidence}));
  for (const double degrees : {10.0, 45.0, 75.0, 85.0}) {
    const auto c = static_cast<float>(std::cos(degrees * 3.141592653589793 / 180.0));
    const double tan_theta = std::tan(std::acos(static_cast<double>(c)));
    const double footprint = 20.0 * tan_theta / (1.0 + 0.25 * tan_theta) * 0.002;
    const Prediction p = chain.predict(surface(20.0f, 0.5f, c), {});
    EXPECT_NEAR(std::sqrt(p.variance_m2), footprint / 2.3548200450309493, 1e-5 * footprint) << degrees;
    EXPECT_NEAR(p.bias_m, 0.5 * footprint, 1e-5 * footprint) << degrees;
    EXPECT_LT(p.variance_m2, footprint_law.predict(surface(20.0f, 0.5f, c), {}).variance_m2) << degrees;
    EXPECT_LT(footprint, 20.0 / 0.25 * 0.002) << degrees;
  }
  for (const float c : {0.9f, 0.2f}) {
    const IdealReturn in = surface(15.0f, 0.5f, c);
    const Prediction p = chain.predict(in, {});
    expect_agreement(sample(chain, in, 64 * 1024), 15.0 + p.bias_m, std::sqrt(p.variance_m2), p.p_detect,
                     label("saturating incidence", c));
  }
}
