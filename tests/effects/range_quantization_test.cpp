// range_quantization (E9): ranges on the wire's lattice, Sheppard's variance.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

TEST(RangeQuantization, RangesLieOnTheLattice) {
  ColumnContext rng15;
  rng15.range_step_m = 0.008f;
  for (const json& quantization :
       {json{{"name", "range_quantization"}, {"step_m", 0.008}}, json{{"name", "range_quantization"}}}) {
    const EffectChain chain = chain_of(json::array({kLinearOs1, quantization}));
    std::vector<IdealReturn> column;
    for (size_t b = 0; b < kBeams; ++b) column.push_back(surface(0.3f + 1.7f * static_cast<float>(b)));
    std::vector<Measurement> out(kBeams);
    size_t checked = 0;
    for (uint32_t c = 0; c < 256; ++c) {
      rng15.column = c;
      chain.simulate(column, rng15, out);
      for (const Measurement& m : out) {
        const double mm = static_cast<double>(m.range_m) * 1000.0;
        const long long whole = std::llround(mm);
        ASSERT_NEAR(mm, static_cast<double>(whole), 0.01) << quantization.dump();
        ASSERT_EQ(whole % 8, 0) << m.range_m << " m is not a multiple of 8 mm";
        ++checked;
      }
    }
    EXPECT_EQ(checked, 256 * kBeams);
    EXPECT_NEAR(chain.predict(surface(10.0f), rng15).quantization_step_m, 0.008, 1e-12);
  }
}

TEST(RangeQuantization, AddsSheppardVariance) {
  // Without noise the error of one range is fixed; over ranges spread across the lattice it is
  // uniform on [-step/2, step/2]: mean 0, variance step^2/12.
  const EffectChain alone = chain_of(json::array({{{"name", "range_quantization"}, {"step_m", 0.008}}}));
  std::vector<IdealReturn> column;
  for (size_t b = 0; b < kBeams; ++b) column.push_back(surface(7.0f + 0.000731f * static_cast<float>(b)));
  std::vector<Measurement> out(kBeams);
  alone.simulate(column, {}, out);
  double sum = 0, sum2 = 0;
  for (size_t b = 0; b < kBeams; ++b) {
    const double e = static_cast<double>(out[b].range_m) - static_cast<double>(column[b].range_m);
    EXPECT_LE(std::abs(e), 0.004 + 1e-6);
    sum += e;
    sum2 += e * e;
  }
  const double predicted = alone.predict(surface(7.0f), {}).variance_m2;
  EXPECT_NEAR(predicted, 0.008 * 0.008 / 12.0, 1e-15);
  EXPECT_NEAR(sum / kBeams, 0.0, 0.0005);
  EXPECT_NEAR(sum2 / kBeams, predicted, 0.15 * predicted);

  // With noise comparable to the step, Sheppard's sigma^2 + step^2/12 holds to well under 1 %.
  const json sigma1cm = {
      {"name", "range_noise_linear"}, {"sigma0_m", 0.01}, {"sigma_max_m", 0.01}, {"range_max_m", 100.0}};
  const EffectChain chain = chain_of(json::array({sigma1cm, {{"name", "range_quantization"}, {"step_m", 0.008}}}));
  for (const float r : {3.0f, 3.004f, 20.0013f}) {
    const Prediction p = chain.predict(surface(r), {});
    expect_agreement(sample(chain, surface(r), 128 * 1024), static_cast<double>(r) + p.bias_m, std::sqrt(p.variance_m2),
                     p.p_detect, label("range_quantization 8 mm", r), 5.0, 0.005);
  }
}
