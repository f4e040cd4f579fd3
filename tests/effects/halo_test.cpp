// halo (E8): beside a retroreflector in its column, pixels lose their returns and gain returns at
// the retroreflector's range, at rates that fall with the rows between them; simulate against
// predict for the detection, halo-first and second-return rates and the halo's range spread, at
// the bounds too.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

constexpr float kRetroRange = 8.0f;

json halo(double probability, double decay_rows, double dropout, double signal = 20.0, double sigma = 0.05) {
  return {{"name", "halo"},         {"probability", probability}, {"decay_rows", decay_rows},
          {"range_sigma_m", sigma}, {"signal_photons", signal},   {"dropout_probability", dropout}};
}

IdealReturn beside_retro(IdealReturn in, int rows) {
  in.retro_rows = static_cast<uint8_t>(rows);
  in.retro_range_m = kRetroRange;
  return in;
}

struct Rates {
  size_t n = 0, detected = 0, halo_first = 0, second = 0;
  double halo_sum = 0.0, halo_sum2 = 0.0;
  double rate(size_t k) const { return static_cast<double>(k) / static_cast<double>(n); }
  double halo_mean() const { return halo_sum / static_cast<double>(halo_first); }
  double halo_sd() const {
    const auto k = static_cast<double>(halo_first);
    return std::sqrt(std::max(0.0, (halo_sum2 - halo_sum * halo_sum / k) / (k - 1.0)));
  }
};

// A halo return is told from the surface's by its SIGNAL, which no surface here has.
Rates simulate(const EffectChain& chain, const IdealReturn& in, float halo_signal, size_t n) {
  Rates out;
  std::vector<Measurement> measured(kBeams);
  const std::vector<IdealReturn> column(kBeams, in);
  ColumnContext context;
  context.seed = in.retro_rows * 1000u + std::bit_cast<uint32_t>(in.range_m);
  for (uint32_t c = 0; out.n < n; ++c) {
    context.column = c % 2048;
    context.frame = c / 2048;
    chain.simulate(column, context, measured);
    for (const Measurement& m : measured) {
      ++out.n;
      out.detected += m.range_m != 0.0f;
      out.second += m.range2_m != 0.0f;
      if (m.range_m != 0.0f && m.signal_photons == halo_signal) {
        ++out.halo_first;
        const double e = static_cast<double>(m.range_m) - static_cast<double>(kRetroRange);
        out.halo_sum += e;
        out.halo_sum2 += e * e;
      }
    }
  }
  return out;
}

// A strong near wall (the halo is its second return), a weak far board (the halo comes first) and
// the sky, 1 to 8 rows from the retroreflector, from no halo to certain halo and dropout.
TEST(Halo, RatesFallWithRowsFromTheRetroreflectorAsPredicted) {
  const EffectChain radiometry = chain_of(json::array({{{"name", "radiometry"}}}));
  const IdealReturn strong = surface(5.0f, 0.5f), weak = surface(60.0f, 0.05f), sky;
  constexpr double kHaloSignal = 20.0;
  ASSERT_GT(radiometry.predict(strong, {}).signal_photons, 10.0 * kHaloSignal);
  ASSERT_LT(radiometry.predict(weak, {}).signal_photons, kHaloSignal);
  struct Case {
    double probability, decay_rows, dropout;
  };
  for (const Case& k :
       {Case{0.0, 1.5, 0.0}, Case{0.3, 1.5, 0.0}, Case{1.0, 20.0, 0.0}, Case{0.5, 0.1, 0.4}, Case{0.2, 3.0, 1.0}}) {
    const EffectChain chain = chain_of(
        json::array({{{"name", "radiometry"}}, kLinearOs1, halo(k.probability, k.decay_rows, k.dropout, kHaloSignal)}));
    for (const int rows : {1, 2, 4, 8}) {
      for (const IdealReturn& surface_in : {strong, weak, sky}) {
        const IdealReturn in = beside_retro(surface_in, rows);
        const Prediction p = chain.predict(in, {});
        const Rates s = simulate(chain, in, static_cast<float>(kHaloSignal), 16 * 1024);
        const auto se = [&s](double q) {
          return std::sqrt(std::max(q * (1.0 - q), 1.0 / static_cast<double>(s.n)) / static_cast<double>(s.n));
        };
        // The halo is the first return in place of the surface (the partner component of the
        // detected, at the retroreflector's range with the halo's own spread), or the only one
        // where the surface gave none.
        const double halo_first = in.hit() ? p.p_detect * (1.0 - p.outlier_mix) * p.partner_mix : p.p_detect;
        if (p.partner_mix > 0.0) {  // off a surface, the halo is all there is (partner_mix 1)
          if (!in.hit()) {
            EXPECT_EQ(p.partner_mix, 1.0);
          }
          EXPECT_NEAR(p.partner_offset_m, static_cast<double>(kRetroRange - in.range_m) - p.bias_m, 1e-6);
          EXPECT_NEAR(std::sqrt(p.variance_m2 + p.partner_extra_variance_m2), 0.05, 1e-9);
        }
        std::printf(
            "  p %.1f decay %4.1f dropout %.1f, %d rows, range %4.1f: detected %.4f vs %.4f, halo first %.4f vs "
            "%.4f, second %.4f vs %.4f\n",
            k.probability, k.decay_rows, k.dropout, rows, static_cast<double>(in.range_m), s.rate(s.detected),
            p.p_detect, s.rate(s.halo_first), halo_first, s.rate(s.second), p.p_second);
        EXPECT_NEAR(s.rate(s.detected), p.p_detect, 5.0 * se(p.p_detect));
        EXPECT_NEAR(s.rate(s.halo_first), halo_first, 5.0 * se(halo_first));
        EXPECT_NEAR(s.rate(s.second), p.p_second, 5.0 * se(p.p_second));
        if (s.halo_first > 100) {  // at the retroreflector's range, with the halo's own spread
          const auto k_halo = static_cast<double>(s.halo_first);
          EXPECT_NEAR(s.halo_mean(), 0.0, 5.0 * 0.05 / std::sqrt(k_halo));
          EXPECT_NEAR(s.halo_sd(), 0.05, 5.0 * 0.05 / std::sqrt(2.0 * k_halo));
        }
      }
    }
  }
}

TEST(Halo, LeavesPixelsAwayFromRetroreflectorsAndTheRetroreflectorItself) {
  const EffectChain plain = chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1}));
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1, halo(1.0, 20.0, 1.0)}));
  IdealReturn retro = surface(8.0f, 0.5f);
  retro.retroreflective = 1;
  for (const IdealReturn& in : {surface(20.0f), retro}) {  // retro_rows 0: none near, or a retro itself
    std::vector<Measurement> a(kBeams), b(kBeams);
    ColumnContext context;
    for (uint32_t c = 0; c < 64; ++c) {
      context.column = c;
      plain.simulate(std::vector<IdealReturn>(kBeams, in), context, a);
      chain.simulate(std::vector<IdealReturn>(kBeams, in), context, b);
      for (size_t beam = 0; beam < kBeams; ++beam) {
        ASSERT_EQ(a[beam].range_m, b[beam].range_m);
        ASSERT_EQ(a[beam].signal_photons, b[beam].signal_photons);
      }
    }
    const Prediction pa = plain.predict(in, {}), pb = chain.predict(in, {});
    EXPECT_EQ(pa.p_detect, pb.p_detect);
    EXPECT_EQ(pa.outlier_mix, pb.outlier_mix);
    EXPECT_EQ(pa.p_second, pb.p_second);
  }
}

TEST(Halo, BadParametersNameTheEffectAndTheParameter) {
  try {
    EffectChain::from_json(json::array({{{"name", "radiometry"}}, halo(0.3, 0.0, 0.0)}),
                           Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "p.json: /effects/1/decay_rows: must be in [0.1, 20], got 0");
  }
  try {
    EffectChain::from_json(json::array({halo(0.3, 1.0, 0.0)}), Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/0: halo needs radiometry earlier in the chain");
  }
}

}  // namespace
