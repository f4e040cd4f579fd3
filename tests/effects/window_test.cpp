// window (E16): transmission and near returns inside an encoder-angle sector only, simulate against
// predict for the signal, the detection rate and the near returns' rates, at the bounds too.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

json window(double start_deg, double width_deg, double transmission, double near_probability = 0.0,
            double near_signal = 20.0) {
  return {{"name", "window"},
          {"sector_start_deg", start_deg},
          {"sector_width_deg", width_deg},
          {"transmission", transmission},
          {"near_return_probability", near_probability},
          {"near_return_range_m", 0.05},
          {"near_return_signal_photons", near_signal}};
}

ColumnContext column_at(uint32_t column, uint32_t width = 1024) {
  ColumnContext context;
  context.column = column;
  context.columns_per_frame = width;
  return context;
}

Measurement first_pixel(const EffectChain& chain, const IdealReturn& in, const ColumnContext& context) {
  std::vector<Measurement> out(kBeams);
  chain.simulate(std::vector<IdealReturn>(kBeams, in), context, out);
  return out[0];
}

TEST(Window, ScalesSignalAndReflectivityOnlyInsideItsSector) {
  const EffectChain plain = chain_of(json::array({{{"name", "radiometry"}}}));
  // 350 to 10 degrees: the sector wraps past 360. At 1024 columns, 28 (9.8 deg) is inside, 30 (10.5) not.
  const EffectChain dirty = chain_of(json::array({{{"name", "radiometry"}}, window(350.0, 20.0, 0.3)}));
  const IdealReturn wall = surface(8.0f, 0.4f);
  for (const uint32_t column : {0u, 28u, 1000u, 1023u}) {
    const ColumnContext context = column_at(column);
    const Measurement clean = first_pixel(plain, wall, context), seen = first_pixel(dirty, wall, context);
    EXPECT_FLOAT_EQ(seen.signal_photons, 0.3f * clean.signal_photons) << column;
    EXPECT_FLOAT_EQ(seen.reflectivity, 0.3f * clean.reflectivity) << column;
    EXPECT_EQ(seen.range_m, clean.range_m) << column;
    EXPECT_DOUBLE_EQ(dirty.predict(wall, context).signal_photons, 0.3 * plain.predict(wall, context).signal_photons);
  }
  for (const uint32_t column : {30u, 512u, 995u}) {
    const ColumnContext context = column_at(column);
    const Measurement clean = first_pixel(plain, wall, context), seen = first_pixel(dirty, wall, context);
    EXPECT_EQ(seen.signal_photons, clean.signal_photons) << column;
    EXPECT_EQ(seen.reflectivity, clean.reflectivity) << column;
    EXPECT_DOUBLE_EQ(dirty.predict(wall, context).signal_photons, plain.predict(wall, context).signal_photons);
  }
  // A retroreflector's logarithmic band is not rescaled.
  IdealReturn sign = wall;
  sign.retroreflective = 1;
  const ColumnContext inside = column_at(0);
  EXPECT_GT(first_pixel(plain, sign, inside).reflectivity, 100.0f);
  EXPECT_EQ(first_pixel(dirty, sign, inside).reflectivity, first_pixel(plain, sign, inside).reflectivity);
}

// Dropout after the window sees the attenuated signal: the no-return rate rises as predicted, from
// clear glass (transmission 1, the upper bound) to a blocked window (0, the lower bound).
TEST(Window, DetectionFollowsTheTransmission) {
  for (const double tau : {1.0, 0.5, 0.2, 0.0}) {
    const EffectChain chain =
        chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1, window(0.0, 360.0, tau), {{"name", "dropout"}}}));
    const IdealReturn target = surface(35.0f, 0.1f);
    const ColumnContext context = column_at(0, 2048);
    const Prediction p = chain.predict(target, context);
    expect_agreement(sample(chain, target, 64 * 1024, context), 35.0 + p.bias_m, std::sqrt(p.variance_m2), p.p_detect,
                     "window transmission " + std::to_string(tau));
  }
}

// The near return's rates: first return when it is the stronger (or the only) one, second return
// otherwise, with the probability predict gives; 0 and 1 are the bounds.
TEST(Window, NearReturnsComeAtTheirRateAndOrderByStrength) {
  const EffectChain radiometry = chain_of(json::array({{{"name", "radiometry"}}}));
  const IdealReturn strong = surface(5.0f, 0.5f), weak = surface(60.0f, 0.05f), sky;
  const double near_signal = 20.0;
  ASSERT_GT(radiometry.predict(strong, {}).signal_photons, 10.0 * near_signal);
  ASSERT_LT(radiometry.predict(weak, {}).signal_photons, near_signal);
  for (const double probability : {0.0, 0.1, 0.6, 1.0}) {
    const EffectChain chain =
        chain_of(json::array({{{"name", "radiometry"}}, window(0.0, 360.0, 1.0, probability, near_signal)}));
    for (const IdealReturn& in : {strong, weak, sky}) {
      const ColumnContext base = column_at(0, 2048);
      const Prediction p = chain.predict(in, base);
      size_t n = 0, near_first = 0, detected = 0, second = 0;
      std::vector<Measurement> out(kBeams);
      const std::vector<IdealReturn> column(kBeams, in);
      for (uint32_t c = 0; n < 32 * 1024; ++c) {
        ColumnContext context = base;
        context.column = c % 2048;
        context.frame = c / 2048;
        chain.simulate(column, context, out);
        for (const Measurement& m : out) {
          ++n;
          detected += m.range_m != 0.0f;
          near_first += m.range_m == 0.05f;
          second += m.range2_m != 0.0f;
          if (m.range2_m != 0.0f) {
            EXPECT_TRUE(m.range_m == 0.05f || m.range2_m == 0.05f);
          }
        }
      }
      const auto rate = [n](size_t k) { return static_cast<double>(k) / static_cast<double>(n); };
      const auto se = [n](double q) { return std::sqrt(std::max(q * (1.0 - q), 1.0 / static_cast<double>(n)) / n); };
      const double expected_near_first = in.hit() ? p.outlier_mix : p.p_detect;
      std::printf("  p %.1f range %5.1f: detected %.4f vs %.4f, near first %.4f vs %.4f, second %.4f vs %.4f\n",
                  probability, static_cast<double>(in.range_m), rate(detected), p.p_detect, rate(near_first),
                  expected_near_first, rate(second), p.p_second);
      EXPECT_NEAR(rate(detected), p.p_detect, 5.0 * se(p.p_detect));
      EXPECT_NEAR(rate(near_first), expected_near_first, 5.0 * se(expected_near_first));
      EXPECT_NEAR(rate(second), in.hit() ? p.p_second : 0.0, 5.0 * se(p.p_second));
    }
  }
}

TEST(Window, BadParametersNameTheEffectAndTheParameter) {
  try {
    EffectChain::from_json(json::array({{{"name", "radiometry"}}, window(10.0, 400.0, 0.5)}),
                           Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "p.json: /effects/1/sector_width_deg: must be in [0, 360], got 400");
  }
  try {
    EffectChain::from_json(json::array({window(10.0, 40.0, 0.5)}), Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/0: window needs radiometry earlier in the chain");
  }
}

}  // namespace
