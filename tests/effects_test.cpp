// The effect chain: for every effect, the sample statistics of simulate match predict (pbrt's
// "Sampling, Normal" style), the laws match independent answers (the paper's formula and Table I,
// the radar equation), the noise is deterministic per counter, and bad JSON is reported by path.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/random/counter_rng.h"

using lidartwin::ColumnContext;
using lidartwin::EffectChain;
using lidartwin::IdealReturn;
using lidartwin::InputError;
using lidartwin::Measurement;
using lidartwin::Prediction;
using nlohmann::json;

namespace {

constexpr size_t kBeams = 128;

IdealReturn surface(float range_m, float reflectivity = 0.5f, float cos_incidence = 1.0f) {
  IdealReturn in;
  in.range_m = range_m;
  in.reflectivity = reflectivity;
  in.cos_incidence = cos_incidence;
  return in;
}

EffectChain chain_of(const json& effects) { return EffectChain::from_json(effects, "test"); }

// Sample statistics of the measured range of one ideal return, simulated in every beam of
// columns 0, 1, ... (each pixel a different counter).
struct Sample {
  size_t n = 0;
  size_t detected = 0;
  double mean = 0.0;
  double sd = 0.0;
  double no_return_rate() const { return 1.0 - static_cast<double>(detected) / static_cast<double>(n); }
};

Sample sample(const EffectChain& chain, const IdealReturn& in, size_t n, ColumnContext context = {}) {
  const std::vector<IdealReturn> column(kBeams, in);
  std::vector<Measurement> out(kBeams);
  context.seed ^= std::bit_cast<uint32_t>(in.range_m);  // independent draws at each grid point
  Sample s;
  double sum = 0.0;
  double sum2 = 0.0;
  for (uint32_t c = 0; s.n < n; ++c) {
    context.frame = c / 2048;
    context.column = c % 2048;
    chain.simulate(column, context, out);
    for (const Measurement& m : out) {
      ++s.n;
      if (m.range_m == 0.0f) continue;
      ++s.detected;
      const double e = static_cast<double>(m.range_m) - static_cast<double>(in.range_m);  // small numbers
      sum += e;
      sum2 += e * e;
    }
  }
  const double k = static_cast<double>(s.detected);
  if (s.detected > 0) s.mean = static_cast<double>(in.range_m) + sum / k;
  if (s.detected > 1) s.sd = std::sqrt(std::max(0.0, (sum2 - sum * sum / k) / (k - 1.0)));
  return s;
}

double normal_pdf(double x) { return std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI); }
double normal_cdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// Moments of N(mu, sigma^2) truncated to [a, b] (written here independently of the effects).
struct Moments {
  double mean;
  double sd;
  double mass;
};
Moments truncated(double mu, double sigma, double a, double b) {
  const double alpha = (a - mu) / sigma;
  const double beta = (b - mu) / sigma;
  const double z = normal_cdf(beta) - normal_cdf(alpha);
  const double pa = normal_pdf(alpha);
  const double pb = std::isfinite(beta) ? normal_pdf(beta) : 0.0;
  const double fb = std::isfinite(beta) ? beta * pb : 0.0;
  const double mean = mu + sigma * (pa - pb) / z;
  const double var = sigma * sigma * (1.0 + (alpha * pa - fb) / z - std::pow((pa - pb) / z, 2));
  return {mean, std::sqrt(var), z};
}

// Checks a sample against a predicted mean, sd and detection probability with tolerances of
// `z` standard errors (plus `extra_sd_rel` for approximations such as Sheppard's correction).
void expect_agreement(const Sample& s, double mean, double sd, double p_detect, const std::string& what, double z = 5.0,
                      double extra_sd_rel = 0.0) {
  const double k = static_cast<double>(s.detected);
  const double n = static_cast<double>(s.n);
  const double rate_se = std::sqrt(std::max(p_detect * (1.0 - p_detect), 1.0 / n) / n);
  const double mean_tol = z * sd / std::sqrt(std::max(k, 1.0)) + 1e-6;
  const double sd_tol = sd * (z / std::sqrt(2.0 * std::max(k, 1.0)) + extra_sd_rel) + 1e-7;
  std::printf("  %-34s n %7zu  no-return %.4f vs %.4f (%+.1f se)", what.c_str(), s.n, s.no_return_rate(),
              1.0 - p_detect, (s.no_return_rate() - (1.0 - p_detect)) / rate_se);
  if (s.detected > 1 && sd > 0) {
    std::printf("  mean %+.2e m (%+.1f se)  sd %.5f vs %.5f (%+.2f %%)", s.mean - mean,
                (s.mean - mean) / (sd / std::sqrt(k)), s.sd, sd, 100.0 * (s.sd / sd - 1.0));
  }
  std::printf("\n");
  EXPECT_NEAR(s.no_return_rate(), 1.0 - p_detect, z * rate_se + 1e-12) << what;
  if (s.detected < 100) return;
  EXPECT_NEAR(s.mean, mean, mean_tol) << what << ": sample mean vs predicted";
  EXPECT_NEAR(s.sd, sd, sd_tol) << what << ": sample sd vs predicted";
}

std::string label(const char* effect, double r) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%s r=%.4g", effect, r);
  return buffer;
}

const json kLinearOs0 = {
    {"name", "range_noise_linear"}, {"sigma0_m", 0.01}, {"sigma_max_m", 0.10}, {"range_max_m", 45.0}};
const json kLinearOs1 = {
    {"name", "range_noise_linear"}, {"sigma0_m", 0.01}, {"sigma_max_m", 0.15}, {"range_max_m", 100.0}};
// The datasheet knot sets of profiles/os0-*.json and os1-*.json: plateaus at Table I's values
// joined by ramps over +-2 % of each bin edge.
const json kKnotsOs0 = json::parse(
    R"([[0.3, 0.02], [0.98, 0.02], [1.02, 0.01], [9.8, 0.01], [10.2, 0.015], [14.7, 0.015], [15.3, 0.05], [45, 0.05]])");
const json kKnotsOs1 = json::parse(
    R"([[0.3, 0.007], [0.98, 0.007], [1.02, 0.01], [19.6, 0.01], [20.4, 0.02], [49.0, 0.02], [51.0, 0.05], [100, 0.05]])");

json piecewise(const json& knots) { return {{"name", "range_noise_piecewise"}, {"points_m", knots}}; }

double predicted_sd(const EffectChain& chain, float r, const ColumnContext& context = {}) {
  return std::sqrt(chain.predict(surface(r), context).variance_m2);
}

}  // namespace

// ---- random: the additions effects rely on ----

TEST(EffectsRandom, ColumnStreamsEqualPerPixelStreams) {
  const lidartwin::ColumnStreams streams(77, 5, 1023, 9);
  for (uint32_t beam = 0; beam < 128; ++beam) {
    EXPECT_EQ(streams(beam).bits(0), lidartwin::RandomStream(77, {5, 1023, beam}, 9).bits(0));
    EXPECT_EQ(streams(beam).bits(7), lidartwin::RandomStream(77, {5, 1023, beam}, 9).bits(7));
  }
}

TEST(EffectsRandom, ZigguratIsStandardNormal) {
  const int n = 1 << 21;
  std::vector<double> z(n);
  double sum = 0, sum2 = 0, sum4 = 0;
  int beyond3 = 0, beyond4 = 0;
  for (int i = 0; i < n; ++i) {
    z[i] = lidartwin::RandomStream(3, {static_cast<uint64_t>(i >> 10), static_cast<uint32_t>(i & 1023), 1}, 4)
               .normal_ziggurat(static_cast<uint32_t>(i % 3));
    sum += z[i];
    sum2 += z[i] * z[i];
    sum4 += z[i] * z[i] * z[i] * z[i];
    beyond3 += std::abs(z[i]) > 3.0;
    beyond4 += std::abs(z[i]) > 4.0;  // the tail beyond R = 3.654 comes from the slow path
  }
  EXPECT_NEAR(sum / n, 0.0, 5.0 / std::sqrt(n));
  EXPECT_NEAR(sum2 / n, 1.0, 5.0 * std::sqrt(2.0 / n));
  EXPECT_NEAR(sum4 / n, 3.0, 5.0 * std::sqrt(96.0 / n));
  const double p3 = 2.0 * normal_cdf(-3.0), p4 = 2.0 * normal_cdf(-4.0);
  EXPECT_NEAR(beyond3, n * p3, 5.0 * std::sqrt(n * p3));
  EXPECT_NEAR(beyond4, n * p4, 5.0 * std::sqrt(n * p4));
  // Kolmogorov-Smirnov against Phi: critical value at alpha = 0.001 is 1.95 / sqrt(n).
  std::sort(z.begin(), z.end());
  double d = 0.0;
  for (int i = 0; i < n; ++i) {
    const double f = normal_cdf(z[i]);
    d = std::max({d, f - static_cast<double>(i) / n, static_cast<double>(i + 1) / n - f});
  }
  std::printf("  ziggurat: mean %.2e var %.5f kurtosis %.4f P(|z|>4) %.2e vs %.2e, KS D %.2e (crit %.2e)\n", sum / n,
              sum2 / n, sum4 / n, static_cast<double>(beyond4) / n, p4, d, 1.95 / std::sqrt(n));
  EXPECT_LT(d, 1.95 / std::sqrt(static_cast<double>(n)));
}

// ---- range_noise_linear (E1a, B0) ----

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

// ---- range_noise_piecewise (E1b, Table I) ----

TEST(RangeNoisePiecewise, PassesThroughKnotsAndIsConstantBeyond) {
  for (const json& knots : {kKnotsOs0, kKnotsOs1}) {
    const EffectChain chain = chain_of(json::array({piecewise(knots)}));
    for (const auto& knot : knots) {
      EXPECT_NEAR(predicted_sd(chain, knot[0].get<float>()), knot[1].get<double>(), 1e-7) << knot.dump();
    }
    EXPECT_DOUBLE_EQ(predicted_sd(chain, 0.1f), knots.front()[1].get<double>());
    EXPECT_DOUBLE_EQ(predicted_sd(chain, 400.0f), knots.back()[1].get<double>());
    // Linear between knots: a ramp's midpoint is the mean of its ends.
    const double r = 0.5 * (knots[1][0].get<double>() + knots[2][0].get<double>());
    EXPECT_NEAR(predicted_sd(chain, static_cast<float>(r)),
                0.5 * (knots[1][1].get<double>() + knots[2][1].get<double>()), 1e-6);
  }
}

TEST(RangeNoisePiecewise, MatchesTableIOfThePaper) {
  // Tejero et al., Table I: precision (1 sigma) of a 10 % Lambertian target per range interval.
  struct Interval {
    double from_m, to_m, sigma_m;
  };
  const std::vector<Interval> os0{{0.3, 1, 0.02}, {1, 10, 0.01}, {10, 15, 0.015}, {15, 45, 0.05}};
  const std::vector<Interval> os1{{0.3, 1, 0.007}, {1, 20, 0.01}, {20, 50, 0.02}, {50, 100, 0.05}};
  for (const auto& [knots, table] : {std::pair{kKnotsOs0, os0}, std::pair{kKnotsOs1, os1}}) {
    const EffectChain chain = chain_of(json::array({piecewise(knots)}));
    for (const Interval& bin : table) {
      // Inside the interval, away from the +-2 % ramps at its edges, sigma is the table's value.
      const double lo = bin.from_m * 1.025, hi = bin.to_m / 1.025;
      for (int i = 0; i <= 20; ++i) {
        const double r = bin.from_m <= 0.3 ? 0.3 + (hi - 0.3) * i / 20.0 : lo + (hi - lo) * i / 20.0;
        EXPECT_NEAR(predicted_sd(chain, static_cast<float>(r)), bin.sigma_m, 1e-9) << "r = " << r;
      }
    }
  }
}

TEST(RangeNoisePiecewise, SamplesMatchPrediction) {
  const EffectChain chain = chain_of(json::array({piecewise(kKnotsOs0)}));
  for (const float r : {0.5f, 1.0f, 5.0f, 12.0f, 15.0f, 30.0f, 60.0f}) {
    const Prediction p = chain.predict(surface(r), {});
    expect_agreement(sample(chain, surface(r), 64 * 1024), static_cast<double>(r) + p.bias_m, std::sqrt(p.variance_m2),
                     p.p_detect, label("range_noise_piecewise", r));
  }
}

// ---- range_limits (E5 range part, E16) ----

TEST(RangeLimits, NoReturnRateAndTruncatedMomentsMatchPrediction) {
  const json sigma5cm = {
      {"name", "range_noise_linear"}, {"sigma0_m", 0.05}, {"sigma_max_m", 0.05}, {"range_max_m", 100.0}};
  const EffectChain chain =
      chain_of(json::array({sigma5cm, {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}}}));
  for (const float r : {0.2f, 0.28f, 0.3f, 0.35f, 50.0f, 99.95f, 100.0f, 100.06f, 100.3f}) {
    const Prediction p = chain.predict(surface(r), {});
    const Moments t = truncated(r, 0.05, 0.3, 100.0);  // independent of the effect's own window
    EXPECT_NEAR(p.p_detect, t.mass, 1e-6);
    EXPECT_NEAR(p.window_min_m, 0.3, 1e-6);
    EXPECT_NEAR(p.window_max_m, 100.0, 1e-6);
    expect_agreement(sample(chain, surface(r), 64 * 1024), t.mean, t.sd, p.p_detect, label("range_limits", r));
  }
}

TEST(RangeLimits, WireRangeLimitsToo) {
  // RNG15 profiles cannot represent more than 262.136 m (E9) even if the limits allow 300 m.
  ColumnContext context;
  context.max_wire_range_m = 262.136f;
  const EffectChain chain = chain_of(json::array({{{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 300.0}}}));
  EXPECT_EQ(chain.predict(surface(262.0f), context).p_detect, 1.0);
  EXPECT_EQ(chain.predict(surface(262.2f), context).p_detect, 0.0);
  EXPECT_EQ(sample(chain, surface(262.0f), 1024, context).detected, 1024u);
  EXPECT_EQ(sample(chain, surface(262.2f), 1024, context).detected, 0u);
  EXPECT_EQ(sample(chain, surface(0.29f), 1024, context).detected, 0u);
  EXPECT_EQ(chain.predict(IdealReturn{}, context).p_detect, 0.0);  // no hit, no return
}

// ---- range_quantization (E9) ----

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

// ---- radiometry (section 2) ----

namespace {
// The radar equation of lidar-physics.md section 2.2 with the default parameters, written again.
double expected_signal(double r, double rho_app, double gain = 1.0, double alpha = 0.0) {
  const double g = 1.0 / (1.0 + std::pow(8.0 / r, 3.8));
  return gain * 1.38e5 * rho_app * g * std::exp(-2.0 * alpha * r) / (r * r);
}
}  // namespace

TEST(Radiometry, SignalFollowsTheRadarEquation) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}, {"attenuation_per_m", 0.002}}}));
  ColumnContext context;
  context.signal_gain = 2.0f;
  double worst = 0.0;
  for (float r = 0.25f; r < 520.0f; r *= 1.0137f) {
    for (const float rho : {0.05f, 0.1f, 0.9f}) {
      for (const float cosine : {1.0f, 0.5f, 0.1f}) {
        const IdealReturn in = surface(r, rho, cosine);
        const double want = expected_signal(r, static_cast<double>(rho * cosine), 2.0, 0.002);
        const double got = chain.predict(in, context).signal_photons;
        worst = std::max(worst, std::abs(got / want - 1.0));
        ASSERT_NEAR(got / want, 1.0, 2e-4) << "r " << r << " rho " << rho << " cos " << cosine;
      }
    }
  }
  std::printf("  radiometry: worst relative error of the tabulated range law %.2e\n", worst);
}

TEST(Radiometry, DefaultsReproduceTheMeasuredSignalLevels) {
  // lidar-physics.md Appendix A, OS1-32 FW 2.1: median S r^2 at reflectivity 8-12 per range band.
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}}}));
  struct Band {
    double from_m, to_m, median_s_r2, tolerance;
  };
  // Far field within 5 %; the near-field roll-off (steep, few samples at 2-4 m) within 35 %.
  for (const Band& band : {Band{2, 4, 244, 0.35}, Band{4, 8, 3369, 0.35}, Band{8, 16, 8238, 0.35},
                           Band{16, 32, 13486, 0.05}, Band{32, 64, 13842, 0.05}}) {
    const float r = static_cast<float>(std::sqrt(band.from_m * band.to_m));
    const double s_r2 = chain.predict(surface(r, 0.1f), {}).signal_photons * static_cast<double>(r * r);
    std::printf("  radiometry: %2.0f-%2.0f m  S r^2 %7.0f vs measured median %6.0f\n", band.from_m, band.to_m, s_r2,
                band.median_s_r2);
    EXPECT_NEAR(s_r2 / band.median_s_r2, 1.0, band.tolerance) << band.from_m << "-" << band.to_m << " m";
  }
}

TEST(Radiometry, ReflectivityAndNearIrChannels) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"},
                                                   {"ambient_photons", 300.0},
                                                   {"sky_photons", 12.0},
                                                   {"retro_reflectance", 50.0},
                                                   {"reflectivity_255", 50.0}}}));
  std::vector<IdealReturn> column{surface(10.0f, 0.5f), surface(10.0f, 0.8f, 0.5f), surface(10.0f, 0.1f), IdealReturn{},
                                  surface(10.0f, 0.3f)};
  column[2].retroreflective = 1;
  column[4].specular = 0.5f;  // normal incidence: the specular lobe adds its full 0.5
  std::vector<Measurement> out(column.size());
  chain.simulate(column, {}, out);
  EXPECT_FLOAT_EQ(out[0].reflectivity, 50.0f);
  EXPECT_FLOAT_EQ(out[1].reflectivity, 40.0f);   // 0.8 * cos 60 deg
  EXPECT_FLOAT_EQ(out[2].reflectivity, 255.0f);  // retro_reflectance == reflectivity_255
  EXPECT_FLOAT_EQ(out[4].reflectivity, 80.0f);
  EXPECT_FLOAT_EQ(out[0].near_ir_photons, 150.0f);
  EXPECT_FLOAT_EQ(out[3].near_ir_photons, 12.0f);  // sky
  EXPECT_EQ(out[3].signal_photons, 0.0f);
  EXPECT_EQ(out[3].range_m, 0.0f);
  // Retroreflectors land in the 101-255 band, monotonically in rho_app.
  float previous = 100.0f;
  for (const double retro : {1.5, 3.0, 10.0, 30.0}) {
    const EffectChain c = chain_of(json::array({{{"name", "radiometry"}, {"retro_reflectance", retro}}}));
    c.simulate(column, {}, out);
    EXPECT_GT(out[2].reflectivity, previous);
    EXPECT_LE(out[2].reflectivity, 255.0f);
    previous = out[2].reflectivity;
  }
}

TEST(Radiometry, SimulateReportsWhatPredictExpects) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1}));
  std::vector<IdealReturn> column;
  for (size_t b = 0; b < kBeams; ++b)
    column.push_back(surface(0.5f + 0.9f * static_cast<float>(b), 0.01f * static_cast<float>(b % 100), 0.7f));
  std::vector<Measurement> out(kBeams);
  ColumnContext context;
  context.signal_gain = 0.5f;
  chain.simulate(column, context, out);
  for (size_t b = 0; b < kBeams; ++b) {
    const Prediction p = chain.predict(column[b], context);
    EXPECT_EQ(static_cast<double>(out[b].signal_photons), p.signal_photons) << b;
    EXPECT_EQ(static_cast<double>(out[b].near_ir_photons), p.near_ir_photons) << b;
  }
}

// ---- dropout (E5) ----

TEST(Dropout, NoReturnRateMatchesPrediction) {
  const EffectChain chain = chain_of(
      json::array({{{"name", "radiometry"}}, kLinearOs1, {{"name", "dropout"}, {"ambient_coefficient", 0.2}}}));
  for (const float r : {10.0f, 30.0f, 40.0f, 50.0f, 60.0f, 80.0f}) {
    const Prediction p = chain.predict(surface(r, 0.1f), {});
    expect_agreement(sample(chain, surface(r, 0.1f), 64 * 1024), static_cast<double>(r) + p.bias_m,
                     std::sqrt(p.variance_m2), p.p_detect, label("dropout rho 0.1", r));
  }
  // The Gen1 OS1 range spec points (40 m at 10 %, 120 m at 80 %) are detected about 90 % of the time.
  const EffectChain defaults = chain_of(json::array({{{"name", "radiometry"}}, {{"name", "dropout"}}}));
  EXPECT_NEAR(defaults.predict(surface(40.0f, 0.1f), {}).p_detect, 0.92, 0.03);
  EXPECT_NEAR(defaults.predict(surface(120.0f, 0.8f), {}).p_detect, 0.90, 0.03);
}

TEST(Dropout, NeedsRadiometryEarlierInTheChain) {
  try {
    EffectChain::from_json(json::array({{{"name", "dropout"}}, {{"name", "radiometry"}}}), "p.json: /effects");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/0: dropout needs radiometry earlier in the chain");
  }
}

// ---- the chain ----

TEST(EffectChain, ProfileChainSamplesMatchPrediction) {
  // The os1-64 chain on the RNG15 wire (8 mm): noise, limits and quantization together.
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}},
                                                  piecewise(kKnotsOs1),
                                                  {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}},
                                                  {{"name", "range_quantization"}}}));
  ColumnContext rng15;
  rng15.range_step_m = 0.008f;
  for (const float r : {2.0f, 15.0f, 35.0f, 70.0f}) {
    const Prediction p = chain.predict(surface(r), rng15);
    expect_agreement(sample(chain, surface(r), 128 * 1024, rng15), static_cast<double>(r) + p.bias_m,
                     std::sqrt(p.variance_m2), p.p_detect, label("os1 chain, 8 mm", r), 5.0, 0.01);
  }
}

TEST(EffectChain, EffectsDrawIndependentNoise) {
  // Two copies of one noise effect get different stream ids: their variances add.
  const EffectChain twice = chain_of(json::array({kLinearOs1, kLinearOs1}));
  EXPECT_NE(twice.effects()[0]->stream_id(), twice.effects()[1]->stream_id());
  const Prediction p = twice.predict(surface(30.0f), {});
  expect_agreement(sample(twice, surface(30.0f), 64 * 1024), 30.0, std::sqrt(p.variance_m2), 1.0,
                   "two linear noises r=30");
}

namespace {
std::vector<Measurement> render_columns(const EffectChain& chain, uint64_t seed, const std::vector<uint32_t>& order) {
  std::vector<IdealReturn> column;
  for (size_t b = 0; b < kBeams; ++b) column.push_back(surface(0.5f + 0.8f * static_cast<float>(b), 0.3f));
  std::vector<Measurement> all(order.size() * kBeams);
  for (const uint32_t c : order) {
    ColumnContext context;
    context.seed = seed;
    context.frame = 3;
    context.column = c;
    chain.simulate(column, context, std::span(all).subspan(c * kBeams, kBeams));
  }
  return all;
}

bool same(const std::vector<Measurement>& a, const std::vector<Measurement>& b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](const Measurement& x, const Measurement& y) {
    return x.range_m == y.range_m && x.signal_photons == y.signal_photons && x.reflectivity == y.reflectivity &&
           x.near_ir_photons == y.near_ir_photons;
  });
}
}  // namespace

TEST(EffectChain, DeterministicInAnyColumnOrderAndThreadSplit) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}},
                                                  kLinearOs1,
                                                  {{"name", "dropout"}},
                                                  {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}},
                                                  {{"name", "range_quantization"}}}));
  std::vector<uint32_t> order(512);
  std::iota(order.begin(), order.end(), 0u);
  const auto reference = render_columns(chain, 42, order);
  EXPECT_TRUE(same(reference, render_columns(chain, 42, order)));
  EXPECT_FALSE(same(reference, render_columns(chain, 43, order)));

  std::mt19937 shuffle_engine(2024);  // fixed seed: the order only needs to differ from 0..n
  std::shuffle(order.begin(), order.end(), shuffle_engine);
  EXPECT_TRUE(same(reference, render_columns(chain, 42, order)));

  std::vector<Measurement> threaded(reference.size());
  std::vector<std::thread> threads;
  for (uint32_t t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      std::vector<uint32_t> mine;
      for (size_t j = t; j < order.size(); j += 4) mine.push_back(order[j]);
      std::vector<IdealReturn> column;
      for (size_t b = 0; b < kBeams; ++b) column.push_back(surface(0.5f + 0.8f * static_cast<float>(b), 0.3f));
      for (const uint32_t c : mine) {
        ColumnContext context;
        context.seed = 42;
        context.frame = 3;
        context.column = c;
        chain.simulate(column, context, std::span(threaded).subspan(c * kBeams, kBeams));
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_TRUE(same(reference, threaded));
}

TEST(EffectChain, ReplacingKeepsOtherEffectsNoise) {
  const EffectChain chain =
      chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1, {{"name", "range_quantization"}}}));
  const auto& noise = *chain.effects()[1];
  const std::vector<double> values{0.02, 0.3, 100.0};
  const EffectChain refit = chain.replacing(1, noise.with_parameters(values));
  EXPECT_EQ(refit.effects()[1]->stream_id(), noise.stream_id());
  EXPECT_EQ(refit.effects()[1]->parameters()[1].value, 0.3);
  const EffectChain longer = chain.with_effect(chain.effects()[1]);
  EXPECT_EQ(longer.effects().size(), 4u);
  EXPECT_NE(longer.effects()[3]->stream_id(), noise.stream_id());  // a new place, a new stream
}

// ---- JSON ----

namespace {
std::string error_of(const json& effects, std::string_view source = "profiles/os1-64.json: /effects") {
  try {
    EffectChain::from_json(effects, source);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(EffectJson, ErrorsNameTheSourcePathAndRange) {
  json effects = json::array({{{"name", "radiometry"}}, {{"name", "range_quantization"}}, kLinearOs1});
  effects[2]["sigma0_m"] = -0.01;
  EXPECT_EQ(error_of(effects), "profiles/os1-64.json: /effects/2/sigma0_m: must be in [0, 1], got -0.01");

  effects[2]["sigma0_m"] = "1 cm";
  EXPECT_EQ(error_of(effects),
            "profiles/os1-64.json: /effects/2/sigma0_m: must be a number in [0, 1], got a string \"1 cm\"");

  effects[2].erase("sigma0_m");
  EXPECT_EQ(error_of(effects),
            "profiles/os1-64.json: /effects/2/sigma0_m: missing; range_noise_linear needs it, a number in [0, 1]");

  effects[2]["sigma0_m"] = 0.01;
  effects[2]["sigma_m"] = 0.01;
  EXPECT_EQ(error_of(effects),
            "profiles/os1-64.json: /effects/2/sigma_m: unknown key of range_noise_linear; "
            "allowed keys here: name, sigma0_m, sigma_max_m, range_max_m");

  EXPECT_EQ(error_of(json::array({{{"name", "range_noise_gaussian"}}})),
            "profiles/os1-64.json: /effects/0/name: unknown effect \"range_noise_gaussian\"; registered effects: "
            "dropout, radiometry, range_limits, range_noise_linear, range_noise_piecewise, range_quantization");
  EXPECT_TRUE(error_of(json::array({{{"sigma0_m", 0.01}}}))
                  .starts_with("profiles/os1-64.json: /effects/0/name: missing; registered effects: dropout,"));
  EXPECT_EQ(error_of(json::object()),
            "profiles/os1-64.json: /effects: must be an array of effects [{\"name\": ...}, ...]");
  EXPECT_EQ(error_of(json::array({{{"name", "range_limits"}, {"min_m", 5}, {"max_m", 1}}})),
            "profiles/os1-64.json: /effects/0/max_m: must be greater than min_m (5), got 1");
  EXPECT_EQ(error_of(json::array({{{"name", "range_quantization"}, {"step_m", true}}}), "file.json"),
            "file.json: /0/step_m: must be a number in [0, 1], got a boolean true");
}

TEST(EffectJson, PiecewiseKnotErrors) {
  const auto knots_error = [](const char* knots) {
    return error_of(json::array({piecewise(json::parse(knots))}), "os0.json: /effects");
  };
  EXPECT_EQ(knots_error("[[1, 0.01]]"), "os0.json: /effects/0/points_m: needs at least 2 knots [range_m, sigma_m]");
  EXPECT_EQ(knots_error("[[1, 0.01], [1, 0.02]]"),
            "os0.json: /effects/0/points_m/1/0: must be greater than the previous knot's range 1, got 1");
  EXPECT_EQ(knots_error("[[1, 0.01], [2, 0]]"), "os0.json: /effects/0/points_m/1/1: must be in [1e-06, 10], got 0");
  EXPECT_EQ(knots_error("[[1, 0.01], [2]]"), "os0.json: /effects/0/points_m/1: must be [range_m, sigma_m]");
  EXPECT_EQ(error_of(json::array({{{"name", "range_noise_piecewise"}}}), "os0.json: /effects"),
            "os0.json: /effects/0/points_m: missing; range_noise_piecewise needs [[range_m, sigma_m], ...]");
}

TEST(EffectJson, WithParametersChecksBounds) {
  const EffectChain chain = chain_of(json::array({kLinearOs1}));
  const std::vector<double> bad{0.01, 0.15, 0.0};
  try {
    (void)chain.effects()[0]->with_parameters(bad);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "range_noise_linear: /range_max_m: must be in [0.1, 10000], got 0");
  }
  const std::vector<double> too_few{0.01};
  EXPECT_THROW((void)chain.effects()[0]->with_parameters(too_few), InputError);
}

TEST(EffectJson, RoundTripsEveryEffect) {
  const json effects = json::array({{{"name", "radiometry"}, {"gain_photons_m2", 2e5}},
                                    piecewise(kKnotsOs1),
                                    kLinearOs0,
                                    {{"name", "dropout"}, {"width", 0.5}},
                                    {{"name", "range_limits"}, {"min_m", 0.5}, {"max_m", 45.0}},
                                    {{"name", "range_quantization"}, {"step_m", 0.001}}});
  const EffectChain chain = chain_of(effects);
  const json out = chain.to_json();
  EXPECT_EQ(out[1]["points_m"], kKnotsOs1);
  EXPECT_EQ(out[0]["gain_photons_m2"], 2e5);
  EXPECT_EQ(out[0]["overlap_range_m"], 8.0);  // defaults are written out
  EXPECT_EQ(chain_of(out).to_json(), out);
  // The piecewise sigmas are fittable, the knot ranges are structure.
  const auto parameters = chain.effects()[1]->parameters();
  ASSERT_EQ(parameters.size(), 16u);
  EXPECT_EQ(parameters[0].name, "points_m/0/0");
  EXPECT_TRUE(parameters[0].fixed);
  EXPECT_FALSE(parameters[1].fixed);
}

TEST(EffectRegistry, ListsBuiltInsAndAcceptsNewEffects) {
  const auto names = lidartwin::registered_effects();
  for (const char* name :
       {"radiometry", "range_noise_linear", "range_noise_piecewise", "range_limits", "range_quantization", "dropout"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  }
  lidartwin::register_effect("test_alias_of_quantization", [](const json& params, std::string_view source) {
    json copy = params;
    copy["name"] = "range_quantization";
    return EffectChain::from_json(json::array({copy}), source)
        .effects()[0]
        ->with_parameters(std::vector<double>{0.001});
  });
  EXPECT_EQ(chain_of(json::array({{{"name", "test_alias_of_quantization"}}})).effects().size(), 1u);
}

// ---- every profile's chain ----

TEST(Profiles, EveryEffectChainBuilds) {
  const std::filesystem::path dir = std::filesystem::path(LIDARTWIN_SOURCE_DIR) / "profiles";
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_directory(dir)) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.path().extension() == ".json") files.push_back(entry.path());
    }
  }
  if (files.empty()) GTEST_SKIP() << "no profiles in " << dir << " yet";
  std::sort(files.begin(), files.end());
  for (const auto& file : files) {
    SCOPED_TRACE(file.string());
    std::ifstream in(file);
    const json document = json::parse(in);
    ASSERT_TRUE(document.contains("effects")) << file;
    const std::string source = "profiles/" + file.filename().string() + ": /effects";
    EffectChain chain;
    ASSERT_NO_THROW(chain = EffectChain::from_json(document.at("effects"), source));
    EXPECT_EQ(chain.effects().size(), document.at("effects").size());
    // A hit inside the profile's range is detected with some noise; no hit stays no return.
    const Prediction p = chain.predict(surface(10.0f, 0.5f), {});
    EXPECT_GT(p.p_detect, 0.5) << file;
    EXPECT_EQ(chain.predict(IdealReturn{}, {}).p_detect, 0.0) << file;
  }
}
