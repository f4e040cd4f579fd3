// mixed_pixels (E6, and E15's second return): a footprint across a depth step gives a return
// between the two surfaces (a step shorter than the pulse) or either surface (a longer one), and
// in the dual profiles a second return; simulate draws what predict says. The checks use the
// sample's own fourth moment for the variance's standard error: a mixed range is not Gaussian.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

constexpr double kDegree = 3.141592653589793 / 180.0;

IdealReturn at_edge(float range_m, float partner_range_m, float spacing_deg, float partner_reflectance = 0.5f) {
  IdealReturn in = surface(range_m, 0.5f, 1.0f);
  in.partner_range_m = partner_range_m;
  in.partner_reflectance = partner_reflectance;
  in.partner_spacing_rad = static_cast<float>(static_cast<double>(spacing_deg) * kDegree);
  return in;
}

json mixed(double divergence_deg, double pulse_length_m = 1.0, double second_fraction = 0.1) {
  return {{"name", "mixed_pixels"},
          {"divergence_rad", divergence_deg * kDegree},
          {"pulse_length_m", pulse_length_m},
          {"second_fraction", second_fraction}};
}

// Draws of one pixel: the first and second returns of each.
struct Draws {
  std::vector<double> first, second;
  size_t n = 0;
};
Draws draw(const EffectChain& chain, const IdealReturn& in, size_t n) {
  const std::vector<IdealReturn> column(kBeams, in);
  std::vector<Measurement> out(kBeams);
  Draws d;
  ColumnContext context;
  context.seed = std::bit_cast<uint32_t>(in.partner_range_m) ^ std::bit_cast<uint32_t>(in.partner_spacing_rad);
  for (uint32_t c = 0; d.n < n; ++c) {
    context.frame = c / 2048;
    context.column = c % 2048;
    chain.simulate(column, context, out);
    for (const Measurement& m : out) {
      ++d.n;
      if (m.range_m > 0.0f) d.first.push_back(m.range_m);
      if (m.range2_m > 0.0f) d.second.push_back(m.range2_m);
    }
  }
  return d;
}

// Mean and variance within 5 standard errors; the variance's from the sample's fourth moment.
void expect_moments(const std::vector<double>& x, double mean, double variance, const std::string& what) {
  const auto n = static_cast<double>(x.size());
  double m1 = 0.0;
  for (const double v : x) m1 += v / n;
  double m2 = 0.0, m4 = 0.0;
  for (const double v : x) m2 += (v - m1) * (v - m1) / n, m4 += std::pow(v - m1, 4) / n;
  std::printf("  %-40s mean %+.3e vs %+.3e  var %.3e vs %.3e\n", what.c_str(), m1, mean, m2, variance);
  EXPECT_NEAR(m1, mean, 5.0 * std::sqrt(m2 / n) + 1e-6) << what;
  EXPECT_NEAR(m2, variance, 5.0 * std::sqrt(std::max(m4 - m2 * m2, 0.0) / n) + 1e-9) << what;
}

void expect_rate(size_t count, size_t n, double p, const std::string& what) {
  const double rate = static_cast<double>(count) / static_cast<double>(n);
  const double se = std::sqrt(std::max(p * (1.0 - p), 1.0 / static_cast<double>(n)) / static_cast<double>(n));
  std::printf("  %-40s rate %.4f vs %.4f (%+.1f se)\n", what.c_str(), rate, p, (rate - p) / se);
  EXPECT_NEAR(rate, p, 5.0 * se) << what;
}

TEST(MixedPixels, AStepShorterThanThePulseGivesAReturnBetweenTheSurfaces) {
  // Divergence from 0.05 degrees to the bound's 2.9, beams 0.18 and 0.7 degrees apart.
  for (const double divergence : {0.05, 0.13, 0.5, 0.05 / kDegree}) {
    for (const float spacing : {0.18f, 0.7f}) {
      const EffectChain chain = chain_of(json::array({mixed(divergence)}));
      const IdealReturn in = at_edge(10.0f, 10.6f, spacing);
      const Prediction p = chain.predict(in, {});
      const Draws d = draw(chain, in, 64 * 1024);
      ASSERT_EQ(d.first.size(), d.n);
      EXPECT_TRUE(d.second.empty()) << "merged echoes give one return";
      EXPECT_GT(p.bias_m, 0.0);
      EXPECT_LT(p.bias_m, 0.3) << "the merged return leans to the pixel's own surface";
      EXPECT_EQ(p.partner_mix, 0.0);
      expect_moments(d.first, 10.0 + p.bias_m, p.variance_m2,
                     "merged, divergence " + std::to_string(divergence) + " spacing " + std::to_string(spacing));
    }
  }
}

TEST(MixedPixels, AStepLongerThanThePulseGivesEitherSurfaceAndASecondReturn) {
  for (const double divergence : {0.13, 0.5}) {
    for (const float partner_reflectance : {0.5f, 0.05f}) {
      for (const double second_fraction : {0.0, 0.1, 0.45}) {
        const EffectChain chain = chain_of(json::array({mixed(divergence, 1.0, second_fraction)}));
        // A pixel on a near board (8 m) whose footprint may reach the wall behind it (20 m), and the
        // wall's pixel whose footprint may reach the board.
        for (const auto& [r, partner] : {std::pair{8.0, 20.0}, std::pair{20.0, 8.0}}) {
          const IdealReturn in =
              at_edge(static_cast<float>(r), static_cast<float>(partner), 0.18f, partner_reflectance);
          const Prediction p = chain.predict(in, {});
          const Draws d = draw(chain, in, 64 * 1024);
          ASSERT_EQ(d.first.size(), d.n);
          const auto at_partner = static_cast<size_t>(
              std::count_if(d.first.begin(), d.first.end(), [&](double x) { return std::abs(x - partner) < 1e-3; }));
          const std::string what = "r " + std::to_string(r) + " partner rho " + std::to_string(partner_reflectance) +
                                   " divergence " + std::to_string(divergence) + " second " +
                                   std::to_string(second_fraction);
          EXPECT_NEAR(p.partner_offset_m, partner - r, 1e-6);
          expect_rate(at_partner, d.n, p.partner_mix, what + ": first return at the partner");
          expect_rate(d.second.size(), d.n, p.p_second, what + ": second returns");
          for (const double x : d.second) ASSERT_TRUE(std::abs(x - r) < 1e-3 || std::abs(x - partner) < 1e-3) << x;
        }
      }
    }
  }
}

TEST(MixedPixels, TheNearSurfaceWinsMoreOftenAndTheFarOneRarely) {
  const EffectChain chain = chain_of(json::array({mixed(0.13, 1.0, 0.02)}));
  // Equal reflectance: the board's echo is (20/8)^2 stronger, so the wall pixel often reports the
  // board and the board pixel rarely the wall.
  const Prediction wall = chain.predict(at_edge(20.0f, 8.0f, 0.18f), {});
  const Prediction board = chain.predict(at_edge(8.0f, 20.0f, 0.18f), {});
  EXPECT_GT(wall.partner_mix, 0.2);
  EXPECT_EQ(board.partner_mix, 0.0);
  EXPECT_GT(board.p_second, 0.0) << "the wall's echo, at most (8/20)^2 / 2 of the board's, comes second";
}

TEST(MixedPixels, NoPartnerOrNoDivergenceLeavesThePixelAlone) {
  const EffectChain chain = chain_of(json::array({mixed(0.13)}));
  const Prediction alone = chain.predict(surface(10.0f), {});
  EXPECT_EQ(alone.bias_m, 0.0);
  EXPECT_EQ(alone.partner_mix, 0.0);
  const Draws d = draw(chain, surface(10.0f), 4096);
  for (const double x : d.first) ASSERT_EQ(x, 10.0);
  const EffectChain pencil = chain_of(json::array({mixed(0.0)}));
  const Draws p = draw(pencil, at_edge(10.0f, 20.0f, 0.18f), 4096);
  for (const double x : p.first) ASSERT_EQ(x, 10.0);
  EXPECT_TRUE(p.second.empty());
}

TEST(MixedPixels, SignalFollowsTheReportedEchosShare) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}}, mixed(0.5)}));
  const IdealReturn in = at_edge(10.0f, 10.5f, 0.18f, 0.0f);  // a black partner: light is lost
  const Prediction p = chain.predict(in, {});
  const Prediction own = chain_of(json::array({{{"name", "radiometry"}}})).predict(surface(10.0f), {});
  EXPECT_LT(p.signal_photons, own.signal_photons);
  EXPECT_GT(p.signal_photons, 0.5 * own.signal_photons);  // at most half the footprint is beyond the edge
}

TEST(MixedPixels, ParametersOutOfBoundsNameTheEffectAndParameter) {
  try {
    chain_of(json::array({{{"name", "mixed_pixels"}, {"pulse_length_m", -1.0}}}));
    FAIL() << "a negative pulse length was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/0/pulse_length_m"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(chain_of(json::array({mixed(0.13)})).needs_edge_partners());
  EXPECT_FALSE(chain_of(json::array({{{"name", "incidence"}}})).needs_edge_partners());
}

}  // namespace
