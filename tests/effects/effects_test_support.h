#pragma once
// What the effect tests share: ideal returns, sampling a chain pixel by pixel, truncated-normal
// moments written independently of the effects, the agreement check of simulate against predict,
// and the paper's and datasheet's parameter sets.
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
using lidartwin::json_reader::Location;
using nlohmann::json;

namespace effects_test {

inline constexpr size_t kBeams = 128;

inline IdealReturn surface(float range_m, float reflectivity = 0.5f, float cos_incidence = 1.0f) {
  IdealReturn in;
  in.range_m = range_m;
  in.reflectivity = reflectivity;
  in.cos_incidence = cos_incidence;
  return in;
}

inline EffectChain chain_of(const json& effects) { return EffectChain::from_json(effects, "test"); }

// Sample statistics of the measured range of one ideal return, simulated in every beam of
// columns 0, 1, ... (each pixel a different counter).
struct Sample {
  size_t n = 0;
  size_t detected = 0;
  double mean = 0.0;
  double sd = 0.0;
  double no_return_rate() const { return 1.0 - static_cast<double>(detected) / static_cast<double>(n); }
};

inline Sample sample(const EffectChain& chain, const IdealReturn& in, size_t n, ColumnContext context = {}) {
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

inline double normal_pdf(double x) { return std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI); }
inline double normal_cdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// Moments of N(mu, sigma^2) truncated to [a, b] (written here independently of the effects).
struct Moments {
  double mean;
  double sd;
  double mass;
};
inline Moments truncated(double mu, double sigma, double a, double b) {
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
inline void expect_agreement(const Sample& s, double mean, double sd, double p_detect, const std::string& what,
                             double z = 5.0, double extra_sd_rel = 0.0) {
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

inline std::string label(const char* effect, double r) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%s r=%.4g", effect, r);
  return buffer;
}

inline const json kLinearOs0 = {
    {"name", "range_noise_linear"}, {"sigma0_m", 0.01}, {"sigma_max_m", 0.10}, {"range_max_m", 45.0}};
inline const json kLinearOs1 = {
    {"name", "range_noise_linear"}, {"sigma0_m", 0.01}, {"sigma_max_m", 0.15}, {"range_max_m", 100.0}};
// The datasheet knot sets of profiles/os0-*.json and os1-*.json: plateaus at Table I's values
// joined by ramps over +-2 % of each bin edge.
inline const json kKnotsOs0 = json::parse(
    R"([[0.3, 0.02], [0.98, 0.02], [1.02, 0.01], [9.8, 0.01], [10.2, 0.015], [14.7, 0.015], [15.3, 0.05], [45, 0.05]])");
inline const json kKnotsOs1 = json::parse(
    R"([[0.3, 0.007], [0.98, 0.007], [1.02, 0.01], [19.6, 0.01], [20.4, 0.02], [49.0, 0.02], [51.0, 0.05], [100, 0.05]])");

inline json piecewise(const json& knots) { return {{"name", "range_noise_piecewise"}, {"points_m", knots}}; }

inline double predicted_sd(const EffectChain& chain, float r, const ColumnContext& context = {}) {
  return std::sqrt(chain.predict(surface(r), context).variance_m2);
}

}  // namespace effects_test
