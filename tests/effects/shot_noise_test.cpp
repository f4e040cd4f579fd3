// shot_noise: SIGNAL and NEAR_IR spread by F (S + B) and F B about their expected values, simulate
// against predict at the bounds (F = 0 and 20) and between; REFLECTIVITY follows SIGNAL.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

struct Moments2 {
  double mean = 0.0;
  double variance = 0.0;
};

Moments2 moments(const std::vector<double>& values) {
  Moments2 m;
  for (const double v : values) m.mean += v;
  m.mean /= static_cast<double>(values.size());
  for (const double v : values) m.variance += (v - m.mean) * (v - m.mean);
  m.variance /= static_cast<double>(values.size() - 1);
  return m;
}

void expect_moments(const std::vector<double>& values, double mean, double variance, const std::string& what) {
  const Moments2 m = moments(values);
  const double n = static_cast<double>(values.size());
  const double mean_se = std::sqrt(std::max(variance, 1e-12) / n);
  const double variance_se = std::max(variance, 1e-12) * std::sqrt(2.0 / (n - 1.0));
  std::printf("  %-28s mean %10.3f vs %10.3f (%+.1f se)  variance %10.3f vs %10.3f (%+.1f se)\n", what.c_str(), m.mean,
              mean, (m.mean - mean) / mean_se, m.variance, variance, (m.variance - variance) / variance_se);
  EXPECT_NEAR(m.mean, mean, 5.0 * mean_se + 1e-4) << what;
  EXPECT_NEAR(m.variance, variance, 5.0 * variance_se + 1e-4) << what;
}

TEST(ShotNoise, SignalAndNearIrSpreadAsPredicted) {
  // A bright unit (20 times the default gain): thousands of photons, so the clamp at 0 never acts.
  const json radiometry = {{"name", "radiometry"}, {"ambient_photons", 400.0}, {"gain_photons_m2", 2.76e6}};
  const EffectChain clean = chain_of(json::array({radiometry}));
  for (const double f : {0.0, 1.0, 4.0, 20.0}) {
    const EffectChain chain = chain_of(json::array({radiometry, {{"name", "shot_noise"}, {"excess_noise_factor", f}}}));
    for (const IdealReturn& in : {surface(4.0f, 0.5f), surface(9.0f, 0.3f)}) {
      const Prediction p = chain.predict(in, {});
      ASSERT_GT(p.signal_photons, 6.0 * std::sqrt(std::max(f, 1.0) * (p.signal_photons + p.near_ir_photons)))
          << "the clamp at 0 must not matter here";
      EXPECT_DOUBLE_EQ(p.signal_variance, f * (p.signal_photons + p.near_ir_photons));
      EXPECT_DOUBLE_EQ(p.near_ir_variance, f * p.near_ir_photons);
      std::vector<Measurement> reference(kBeams);
      clean.simulate(std::vector<IdealReturn>(kBeams, in), {}, reference);
      const double reflectivity_per_photon =
          static_cast<double>(reference[0].reflectivity) / static_cast<double>(reference[0].signal_photons);
      std::vector<double> signal, near_ir;
      std::vector<Measurement> out(kBeams);
      size_t reflectivity_off = 0;
      for (uint32_t c = 0; signal.size() < 64 * 1024; ++c) {
        ColumnContext context;
        context.column = c;
        chain.simulate(std::vector<IdealReturn>(kBeams, in), context, out);
        for (const Measurement& m : out) {
          signal.push_back(m.signal_photons);
          near_ir.push_back(m.near_ir_photons);
          const double expected = reflectivity_per_photon * static_cast<double>(m.signal_photons);
          reflectivity_off += std::abs(static_cast<double>(m.reflectivity) - expected) > 1e-3 * expected + 1e-4;
        }
      }
      char what[64];
      std::snprintf(what, sizeof what, "F %.0f r %.1f SIGNAL", f, static_cast<double>(in.range_m));
      expect_moments(signal, p.signal_photons, p.signal_variance, what);
      std::snprintf(what, sizeof what, "F %.0f r %.1f NEAR_IR", f, static_cast<double>(in.range_m));
      expect_moments(near_ir, p.near_ir_photons, p.near_ir_variance, what);
      EXPECT_EQ(reflectivity_off, 0u) << "REFLECTIVITY follows SIGNAL";
    }
  }
}

TEST(ShotNoise, NoReturnStaysNoReturn) {
  const EffectChain chain = chain_of(json::array(
      {{{"name", "radiometry"}, {"sky_photons", 300.0}}, {{"name", "shot_noise"}, {"excess_noise_factor", 2.0}}}));
  std::vector<Measurement> out(kBeams);
  chain.simulate(std::vector<IdealReturn>(kBeams), {}, out);
  size_t varied = 0;
  for (const Measurement& m : out) {
    EXPECT_EQ(m.range_m, 0.0f);
    EXPECT_EQ(m.signal_photons, 0.0f);
    varied += m.near_ir_photons != 300.0f;
  }
  EXPECT_GT(varied, kBeams / 2) << "the sky's NEAR_IR is noisy too";
}

}  // namespace
