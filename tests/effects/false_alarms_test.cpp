// false_alarms (E14): pixels without a return become points at a rate proportional to the ambient,
// at ranges uniform over the window; simulate against predict, at the bounds too.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

json radiometry_in_sun(double sky_photons) {
  return {{"name", "radiometry"}, {"ambient_photons", 1000.0}, {"sky_photons", sky_photons}};
}

json false_alarms(double probability) {
  return {{"name", "false_alarms"},
          {"probability_at_reference", probability},
          {"reference_near_ir_photons", 1000.0},
          {"max_range_m", 80.0},
          {"signal_photons", 3.0}};
}

// Sky pixels: the detection rate is p_fa, proportional to NEAR_IR and clamped at 1; the ranges are
// uniform over (0, 80] m: mean 40 m, sd 80 / sqrt(12) m.
TEST(FalseAlarms, SkyPixelsFireAtTheAmbientRateAtUniformRanges) {
  const IdealReturn sky;
  for (const double probability : {0.0, 0.01, 0.2, 1.0}) {
    for (const double near_ir : {500.0, 3000.0}) {
      const EffectChain chain = chain_of(json::array({radiometry_in_sun(near_ir), false_alarms(probability)}));
      const Prediction p = chain.predict(sky, {});
      EXPECT_DOUBLE_EQ(p.p_detect, std::min(1.0, probability * near_ir / 1000.0));
      EXPECT_DOUBLE_EQ(p.outlier_mix, p.p_detect > 0.0 ? 1.0 : 0.0);
      char what[64];
      std::snprintf(what, sizeof what, "false alarms p %.2f B %.0f", probability, near_ir);
      expect_agreement(sample(chain, sky, 128 * 1024), 40.0, 80.0 / std::sqrt(12.0), p.p_detect, what);
    }
  }
}

// Behind dropout a missed surface can fire too: the detection rate rises by (1 - P_det) p_fa, and
// that share of the returns lies off the surface (the uniform outlier component).
TEST(FalseAlarms, DroppedReturnsFireAsOutliers) {
  const EffectChain chain = chain_of(json::array(
      {radiometry_in_sun(0.0), kLinearOs1, {{"name", "dropout"}, {"threshold_photons", 8.0}}, false_alarms(0.5)}));
  const IdealReturn target = surface(40.0f, 0.1f);  // NEAR_IR 100: p_fa = 0.05
  const Prediction p = chain.predict(target, {});
  ASSERT_GT(p.outlier_mix, 0.01);
  const std::vector<IdealReturn> column(kBeams, target);
  std::vector<Measurement> out(kBeams);
  size_t n = 0, detected = 0, off_surface = 0;
  for (uint32_t c = 0; n < 256 * 1024; ++c) {
    ColumnContext context;
    context.frame = c / 2048;
    context.column = c % 2048;
    chain.simulate(column, context, out);
    for (const Measurement& m : out) {
      ++n;
      if (m.range_m == 0.0f) continue;
      ++detected;
      off_surface += std::abs(m.range_m - 40.0f) > 1.0f;  // 1 m: beyond 20 sigma of the noise
    }
  }
  const double rate = static_cast<double>(detected) / static_cast<double>(n);
  const double off = static_cast<double>(off_surface) / static_cast<double>(detected);
  // A false alarm within 1 m of the surface is not counted off it: 2 m of the 80 m window.
  const double expected_off = p.outlier_mix * (1.0 - 2.0 / 80.0);
  const double rate_se = std::sqrt(p.p_detect * (1.0 - p.p_detect) / static_cast<double>(n));
  const double off_se = std::sqrt(expected_off * (1.0 - expected_off) / static_cast<double>(detected));
  std::printf("  detected %.4f vs %.4f (%+.1f se), off the surface %.4f vs %.4f (%+.1f se)\n", rate, p.p_detect,
              (rate - p.p_detect) / rate_se, off, expected_off, (off - expected_off) / off_se);
  EXPECT_NEAR(rate, p.p_detect, 5.0 * rate_se);
  EXPECT_NEAR(off, expected_off, 5.0 * off_se);
}

TEST(FalseAlarms, NeedsRadiometryAndBoundedParameters) {
  try {
    EffectChain::from_json(json::array({false_alarms(0.1)}), Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/0: false_alarms needs radiometry earlier in the chain");
  }
  try {
    EffectChain::from_json(json::array({radiometry_in_sun(10.0), false_alarms(1.5)}), Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/1/probability_at_reference: must be in [0, 1], got 1.5");
  }
}

}  // namespace
