// signal_outliers (E2's tails): a share of the returns, the larger the weaker the signal, lies in a
// wider Gaussian about the same mean; simulate draws what predict says: the share, the spread of
// the mixture and the returns beyond 5 of the core's sigmas.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace signal_outliers_test {

const json kRadiometry = {{"name", "radiometry"}};
const json kTails = {
    {"name", "signal_outliers"}, {"probability", 0.2}, {"half_signal_photons", 20.0}, {"sigma_m", 0.1}};

TEST(SignalOutliers, TheShareFallsWithTheSignal) {
  const EffectChain chain = chain_of(json::array({kRadiometry, kLinearOs1, kTails}));
  const Prediction dark = chain.predict(surface(30.0f, 0.02f), {});
  const Prediction bright = chain.predict(surface(5.0f, 0.9f), {});
  EXPECT_NEAR(dark.tail_mix, 0.2 / (1.0 + dark.signal_photons / 20.0), 1e-12);
  EXPECT_NEAR(bright.tail_mix, 0.2 / (1.0 + bright.signal_photons / 20.0), 1e-12);
  EXPECT_GT(dark.tail_mix, 5.0 * bright.tail_mix);
  EXPECT_DOUBLE_EQ(dark.tail_extra_variance_m2, 0.01);
  // Off by default: no share at all.
  const Prediction off = chain_of(json::array({kRadiometry, kLinearOs1, {{"name", "signal_outliers"}}}))
                             .predict(surface(30.0f, 0.02f), {});
  EXPECT_EQ(off.tail_mix, 0.0);
}

// The mixture's variance is the core's plus share x sigma_m^2; the returns beyond 5 core sigmas
// are the tail's share of them (the core's own are 6e-7).
TEST(SignalOutliers, SamplesMatchPrediction) {
  const EffectChain chain = chain_of(json::array({kRadiometry, kLinearOs1, kTails}));
  for (const float rho : {0.02f, 0.3f}) {
    const IdealReturn in = surface(20.0f, rho);
    const Prediction p = chain.predict(in, {});
    const double pi = p.tail_mix, core = std::sqrt(p.variance_m2);
    const double tail = std::sqrt(p.variance_m2 + p.tail_extra_variance_m2);
    expect_agreement(sample(chain, in, 256 * 1024), 20.0, std::sqrt(p.variance_m2 + pi * p.tail_extra_variance_m2),
                     p.p_detect, label("signal_outliers", rho));
    const std::vector<IdealReturn> column(kBeams, in);
    std::vector<Measurement> out(kBeams);
    size_t n = 0, beyond = 0;
    for (uint32_t c = 0; n < 256 * 1024; ++c) {
      ColumnContext context;
      context.seed = 11;
      context.frame = c / 2048;
      context.column = c % 2048;
      chain.simulate(column, context, out);
      for (const Measurement& m : out) {
        ++n;
        beyond += std::abs(static_cast<double>(m.range_m) - 20.0) > 5.0 * core;
      }
    }
    const double expected = pi * 2.0 * normal_cdf(-5.0 * core / tail) + (1.0 - pi) * 2.0 * normal_cdf(-5.0);
    const double share = static_cast<double>(beyond) / static_cast<double>(n);
    const double se = std::sqrt(expected * (1.0 - expected) / static_cast<double>(n));
    std::printf("  reflectivity %.2f: tail share %.4f, beyond 5 sigma %.4f vs %.4f (%+.1f se)\n",
                static_cast<double>(rho), pi, share, expected, (share - expected) / se);
    EXPECT_NEAR(share, expected, 5.0 * se);
  }
}

TEST(SignalOutliers, NeedsRadiometryFirst) {
  try {
    EffectChain::from_json(json::array({kLinearOs1, kTails}), Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/1: signal_outliers needs radiometry earlier in the chain");
  }
}

}  // namespace signal_outliers_test
