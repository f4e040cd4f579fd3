// The per-pixel likelihood against draws made here from the distribution it claims to score: if
// the model is true, the mean NLL is what expected_nll says, PIT is uniform and z is standard.
#include "lidartwin/analysis/pixel_likelihood.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <hwy/targets.h>

namespace lidartwin {
namespace {

TEST(NormalInterval, KeepsItsDigitsInTheTails) {
  EXPECT_NEAR(normal_interval(-1.0, 1.0), 0.682689492137086, 1e-14);
  // Phi(-8) - Phi(-9): the plain CDF difference at +8..+9 would round to 0.
  EXPECT_NEAR(normal_interval(8.0, 9.0) / 6.2198e-16, 1.0, 1e-3);
  EXPECT_NEAR(normal_interval(-9.0, -8.0) / 6.2198e-16, 1.0, 1e-3);
  EXPECT_EQ(normal_interval(1.0, 1.0), 0.0);
}

// Narrow bins (a quantized range, step << sigma) take the midpoint rule with its corrections: it
// must agree with the CDF difference (evaluated here in long double) to 1e-7 relative wherever
// it is used, up to the width and distance where the CDF takes over again.
TEST(NormalInterval, NarrowBinsAgreeWithTheCdfDifference) {
  const auto exact = [](long double a, long double b) {  // on the upper side, where erfc keeps its digits
    const long double k = 0.70710678118654752440L;
    if (a + b < 0.0L) {  // the mirror image
      const long double lo = -b, hi = -a;
      a = lo;
      b = hi;
    }
    return static_cast<double>(0.5L * (std::erfc(a * k) - std::erfc(b * k)));
  };
  double worst = 0.0;
  for (const double h : {0.001, 0.01, 0.05, 0.1, 0.11}) {
    for (double c = -12.0; c <= 12.0; c += 0.01) {
      const double a = c - 0.5 * h, b = c + 0.5 * h;
      const double want = exact(a, b);
      if (want < 1e-280) continue;
      worst = std::max(worst, std::abs(normal_interval(a, b) / want - 1.0));
    }
  }
  EXPECT_LT(worst, 1e-7);
}

struct Case {
  std::string name;
  RangeModel model;
};
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

// A draw from the model as the sensor would report it: detected or not, then the Gaussian
// mixture (the pixel's own, its tail's and the partner's component) truncated to the window
// (rejection), or the uniform outlier, rounded to the bin grid.
double draw(const RangeModel& m, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  if (u(rng) >= m.p_detect) return 0.0;
  double r = 0.0;
  if (u(rng) < m.outlier_mix) {
    r = m.window_min_m + u(rng) * (m.window_max_m - m.window_min_m);
  } else {
    std::normal_distribution<double> n(0.0, 1.0);
    do {
      if (u(rng) < m.partner_mix) {
        r = m.mean_m + m.partner_offset_m + m.partner_sigma() * n(rng);
      } else {
        r = m.mean_m + (u(rng) < m.tail_mix ? m.tail_sigma_m : m.sigma_m) * n(rng);
      }
    } while (r < m.window_min_m || r > m.window_max_m);
  }
  return std::round(r / m.step_m) * m.step_m;
}

class ScorePixelUnderItsModel : public ::testing::TestWithParam<Case> {};

TEST_P(ScorePixelUnderItsModel, NllMatchesItsExpectationAndPitIsUniform) {
  const RangeModel& m = GetParam().model;
  std::mt19937_64 rng(42);
  constexpr int kDraws = 200'000;
  const NllMoments expected = expected_nll(m);
  double nll = 0.0, z = 0.0, z2 = 0.0;
  int returns = 0;
  std::vector<int> pit(10, 0);
  for (int i = 0; i < kDraws; ++i) {
    const double r = draw(m, rng);
    const PixelScore s = score_pixel(m, r, std::uniform_real_distribution<double>(0, 1)(rng));
    ASSERT_FALSE(s.impossible) << "range " << r;
    nll += s.nll;
    if (r <= 0.0) continue;
    ++pit[static_cast<size_t>(std::min(9.0, s.pit * 10.0))];
    if (std::abs(s.z) <= 5.0) {  // the analysis counts returns beyond 5 sigma as outliers
      ++returns;
      z += s.z;
      z2 += s.z * s.z;
    }
  }
  const int detected = std::accumulate(pit.begin(), pit.end(), 0);
  const double se = std::sqrt(expected.variance / kDraws);
  EXPECT_NEAR(nll / kDraws, expected.mean, 4.0 * se) << "se " << se;
  // z is standardized by the pixel's own truncated Gaussian: where a partner's component overlaps
  // it, returns within 5 sigma come from both, and z says nothing about either alone.
  const bool overlapping =
      m.partner_mix > 0.0 && std::abs(m.partner_offset_m) < 10.0 * std::max(m.sigma_m, m.partner_sigma());
  const double zm = z / returns;
  const double shep = 1.0;  // bins add step^2/12
  const double sheppard = m.step_m * m.step_m / (12.0 * m.sigma_m * m.sigma_m);
  if (m.tail_mix > 0.0 && !overlapping) {
    // E2's tails put some of their returns within 5 sigma too: z^2 of the inliers is the mixture's
    // within +-5 (a normal's second moment inside +-a: P(|x| < a) - 2 a phi(a)), in the core's sigmas.
    const double k = m.tail_sigma_m / m.sigma_m, a = 5.0 / k;
    const double inside = std::erf(a / std::sqrt(2.0));
    const double second = k * k * (inside - 2.0 * a * std::exp(-0.5 * a * a) / std::sqrt(2.0 * M_PI));
    const double tail = m.tail_mix;  // of the pixel's own returns (no partner overlaps here)
    const double expected_z2 = ((1.0 - tail) + tail * second) / ((1.0 - tail) + tail * inside);
    EXPECT_NEAR(zm, 0.0, 0.02);
    // Bins wider than sigma (RNG15's 8 mm against 6 mm) put the 5-sigma cut on their edges: the
    // formula holds to about Sheppard's term there.
    EXPECT_NEAR(z2 / returns - zm * zm, expected_z2 + sheppard, 0.03 * expected_z2 + 0.5 * sheppard);
  } else if (!overlapping) {
    EXPECT_NEAR(zm, 0.0, 0.02);
    EXPECT_NEAR(z2 / returns - zm * zm, shep + sheppard, 0.03);
  }
  double chi2 = 0.0;
  for (const int count : pit) chi2 += std::pow(count - detected / 10.0, 2) / (detected / 10.0);
  EXPECT_LT(chi2, 30.0) << "PIT not uniform (9 dof; 30 is p < 0.001)";
}

RangeModel model(double mean, double sigma, double step, double p_detect = 1.0, double lo = 0.3, double hi = 100.0,
                 double outliers = 0.0) {
  return {mean, sigma, p_detect, outliers, lo, hi, step};
}
// With a partner component (E6's edge partner, E8's halo): weight, offset and its own sigma.
RangeModel with_partner(RangeModel m, double mix, double offset, double sigma) {
  m.partner_mix = mix;
  m.partner_offset_m = offset;
  m.partner_sigma_m = sigma;
  return m;
}
// With E2's tails: this share of the pixel's own returns with this sigma.
RangeModel with_tail(RangeModel m, double mix, double sigma) {
  m.tail_mix = mix;
  m.tail_sigma_m = sigma;
  return m;
}

INSTANTIATE_TEST_SUITE_P(
    Models, ScorePixelUnderItsModel,
    ::testing::Values(Case{"wide_gaussian_1mm_bins", model(12.0, 0.02, 0.001)},
                      Case{"narrow_gaussian_exact_bins", model(3.0, 0.0007, 0.001)},
                      Case{"rng15_8mm_bins", model(25.0, 0.006, 0.008, 0.9)},
                      Case{"truncated_at_max_range", model(100.02, 0.05, 0.001, 0.4)},
                      Case{"with_outliers", model(40.0, 0.03, 0.001, 1.0, 0.3, 100.0, 0.001)},
                      Case{"edge_partner", with_partner(model(8.0, 0.01, 0.001), 0.3, 0.6, 0.0)},
                      Case{"halo_with_its_own_spread",
                           with_partner(model(8.0, 0.01, 0.001, 0.95, 0.3, 100.0, 0.002), 0.2, -0.4, 0.05)},
                      // A halo beside a retroreflector on the same board: its
                      // component overlaps the surface's own.
                      Case{"halo_overlapping_the_surface", with_partner(model(8.0, 0.01, 0.001), 0.3, 0.005, 0.02)},
                      Case{"edge_partner_one_sigma_away", with_partner(model(8.0, 0.01, 0.001), 0.5, 0.01, 0.0)},
                      Case{"tails_1mm_bins", with_tail(model(8.0, 0.01, 0.001), 0.2, 0.1)},
                      // crc_test.pcap's dark targets: RNG15's 8 mm bins wider than the core's sigma.
                      Case{"tails_rng15_8mm_bins", with_tail(model(1.5, 0.006, 0.008), 0.15, 0.15)},
                      Case{"tails_near_the_window", with_tail(model(0.5, 0.01, 0.001, 0.9), 0.3, 0.2)},
                      Case{"tails_beside_an_edge_partner",
                           with_tail(with_partner(model(8.0, 0.01, 0.001), 0.3, 0.6, 0.0), 0.1, 0.05)}),
    [](const auto& test_info) { return test_info.param.name; });

TEST(ScorePixel, WhatTheModelRulesOutCostsAFiniteVisibleAmount) {
  const RangeModel certain = model(10.0, 0.01, 0.001, 1.0);
  const PixelScore miss = score_pixel(certain, 0.0, 0.5);
  EXPECT_TRUE(miss.impossible);
  EXPECT_NEAR(miss.nll, -std::log(kImpossible), 1e-9);
  const PixelScore far_off = score_pixel(certain, 12.0, 0.5);  // 200 sigma
  EXPECT_TRUE(far_off.impossible);
  EXPECT_TRUE(std::isfinite(far_off.nll));
  const RangeModel nothing_there = model(0.0, 0.0, 0.001, 0.0);
  const PixelScore ghost = score_pixel(nothing_there, 5.0, 0.5);
  EXPECT_TRUE(ghost.impossible);
  EXPECT_GT(ghost.nll, -std::log(kImpossible));
  EXPECT_FALSE(score_pixel(nothing_there, 0.0, 0.5).impossible);
  EXPECT_EQ(score_pixel(nothing_there, 0.0, 0.5).nll, 0.0);
}

// expected_nll, which score_pixels computes for every pixel, against its definition: the sum over
// the bins of P(bin) times the NLL pixel_nll gives a return in it. A lone Gaussian and E2's tails
// (cores narrower and wider than the tail, tails from a trace to half the returns, from as narrow
// as the core to 60 times as wide, a depth edge's partner far behind or none), bins from 1/20 of the narrower sigma to
// the quarter where the bin-by-bin sum takes over; to 2e-5 nats, far below what a capture's excess could show (without
// the bins' own h^2 / 24, 2.6e-3 at a quarter sigma: +0.5 standard errors on a 600 k pixel capture).
TEST(ExpectedNll, IsTheSumOverTheBinsOfPTimesTheNll) {
  for (const double h : {0.05, 0.25}) {
    for (const double sigma : {0.02, 0.05}) {
      for (const double ratio : {0.5, 1.0, 1.3, 4.0, 20.0, 60.0}) {
        for (const double mix : {0.0, 1e-4, 0.01, 0.08, 0.5}) {
          for (const double partner : {0.0, 0.3}) {  // at a depth edge, a partner's return far behind
            const double step = h * std::min(sigma, ratio * sigma);
            const double reach = 12.0 * std::max(sigma, ratio * sigma);
            RangeModel m = with_tail(model(50.0, sigma, step), mix, ratio * sigma);
            if (partner > 0.0) m = with_partner(m, partner, -(reach + 0.5), 0.03);
            // (bins the model rules out are floored at kImpossible times one uniform bin: left out)
            const double floored = kImpossible * step / (m.window_max_m - m.window_min_m);
            long double mean = 0.0L, square = 0.0L;
            const double first = m.mean_m + std::min(-reach, m.partner_offset_m - 0.5);
            for (double k = std::round(first / step); k * step <= m.mean_m + reach; k += 1.0) {
              const long double nll = pixel_nll(m, k * step), p = std::exp(-nll);
              if (p < 1.001 * floored) continue;
              mean += p * nll;
              square += p * nll * nll;
            }
            const NllMoments expected = expected_nll(m);
            const std::string what = "bins " + std::to_string(h) + " sigma, sigma " + std::to_string(sigma) +
                                     ", tail x" + std::to_string(ratio) + ", mix " + std::to_string(mix) +
                                     ", partner " + std::to_string(partner);
            EXPECT_NEAR(expected.mean, static_cast<double>(mean), 2e-5) << what;
            EXPECT_NEAR(expected.variance, static_cast<double>(square - mean * mean), 2e-5) << what;
          }
        }
      }
    }
  }
}

// pixel_nll, what the fits evaluate, takes the log of the common case's probability in closed form
// (no exp, one log); score_pixel, what compare reports, computes it in full. They must agree to
// rounding wherever either is used: across sigmas narrow and wide against the bin, returns near
// and far out (to where the probability is floored), low and certain detection, and the cases the
// closed form leaves to the full computation (outliers, a partner, a window cutting the Gaussian).
TEST(PixelNll, EqualsScorePixelsNllInEveryCase) {
  size_t compared = 0;
  for (const double sigma : {0.002, 0.009, 0.0101, 0.03, 0.5}) {
    for (const double p_detect : {1.0, 0.93, 1e-3}) {
      std::vector<RangeModel> models = {model(20.0, sigma, 0.001, p_detect)};
      models.push_back(models.front());
      models.back().outlier_mix = 0.01;
      models.push_back(with_partner(models.front(), 0.2, 0.3, 0.0));
      models.push_back(models.front());
      models.back().window_max_m = 20.0 + 3.0 * sigma;  // the window cuts the Gaussian
      for (const RangeModel& m : models) {
        for (double z = -40.0; z <= 40.0; z += 0.37) {
          const double measured = std::round((m.mean_m + z * sigma) / m.step_m) * m.step_m;
          if (measured <= 0.0) continue;
          const double full = score_pixel(m, measured, 0.5).nll;
          EXPECT_NEAR(pixel_nll(m, measured), full, 1e-12 * std::max(1.0, std::abs(full)))
              << "sigma " << sigma << " p_detect " << p_detect << " z " << z;
          ++compared;
        }
      }
    }
  }
  EXPECT_GT(compared, 10000u);
}

// Models in the common case (pixel_nlls' SIMD kernel) and out of it, with returns near and far.
struct Batch {
  std::vector<RangeModel> models;
  std::vector<double> measured;
};
Batch mixed_batch() {
  Batch b;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 5003; ++i) {  // not a multiple of any vector width
    RangeModel m = model(1.0 + 60.0 * u(rng), 0.0105 + 0.3 * u(rng) * u(rng), i % 7 == 0 ? 0.008 : 0.001,
                         i % 5 == 0 ? 1.0 : 1e-5 + u(rng));
    if (i % 11 == 0) m.outlier_mix = 0.01;
    if (i % 13 == 0) m = with_partner(m, 0.3, 0.2, 0.0);
    const double z = (u(rng) - 0.5) * (i % 17 == 0 ? 200.0 : 8.0);
    b.measured.push_back(i % 19 == 0 ? 0.0
                                     : std::max(0.0, std::round((m.mean_m + z * m.sigma_m) / m.step_m) * m.step_m));
    b.models.push_back(m);
  }
  return b;
}

// The batch gives what each model's pixel_nll gives, and in the common case what the closed form
// gives in long double (its logarithm is the kernel's own, within an ulp or two of libm's).
TEST(PixelNlls, EqualsPixelNllAndTheClosedFormInLongDouble) {
  const Batch b = mixed_batch();
  std::vector<double> out(b.models.size());
  pixel_nlls(b.models, b.measured, out);
  size_t closed = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    const RangeModel& m = b.models[i];
    EXPECT_EQ(out[i], pixel_nll(m, b.measured[i])) << i;
    // score_pixel takes the bin's edges in sigmas and their difference: at 60 m its width is off by an
    // ulp of the range over the step (1e-11 of it), which the common case avoids.
    EXPECT_NEAR(out[i], score_pixel(m, b.measured[i], 0.5).nll, 2e-11 + 1e-12 * std::abs(out[i])) << i;
    const long double inverse = 1.0L / m.sigma_m, c = (b.measured[i] - m.mean_m) * inverse, h = m.step_m * inverse;
    const bool whole_window =
        (m.window_min_m - m.mean_m) * inverse < -8.5L && (m.window_max_m - m.mean_m) * inverse > 8.5L;
    if (m.outlier_mix > 0.0 || m.partner_mix > 0.0 || b.measured[i] <= 0.0 || !whole_window || h > 0.1L ||
        std::abs(c) * h > 0.5L) {
      continue;
    }
    const long double c2 = c * c, h2 = h * h;
    const long double p =
        m.p_detect * h * (1.0L + (c2 - 1.0L) * h2 / 24.0L + (c2 * c2 - 6.0L * c2 + 3.0L) * h2 * h2 / 1920.0L);
    const long double want = 0.5L * c2 + 0.918938533204672741780329736L - std::log(p);
    if (want > 13.8) continue;  // floored: the full computation's
    EXPECT_NEAR(out[i], static_cast<double>(want), 4e-15 * std::max(1.0L, std::abs(want))) << i;
    ++closed;
  }
  EXPECT_GT(closed, 2000u);
}

// Every Highway target the CPU runs gives the same bits (multiplies, adds and a division alone),
// so a diagnosis fits the same values on every CPU.
TEST(PixelNlls, EveryTargetGivesTheSameBits) {
  const Batch b = mixed_batch();
  std::vector<double> first;
  for (const int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    std::vector<double> out(b.models.size());
    pixel_nlls(b.models, b.measured, out);
    if (first.empty()) {
      first = out;
    } else {
      for (size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], first[i]) << hwy::TargetName(target) << " row " << i;
    }
  }
  hwy::SetSupportedTargetsForTest(0);
  EXPECT_FALSE(first.empty());
}

TEST(RangeModel, QuantizationVarianceFoldedByTheChainIsTakenBackOut) {
  Prediction p;
  p.variance_m2 = 0.01 * 0.01 + 0.008 * 0.008 / 12.0;
  p.quantization_step_m = 0.008;
  p.p_detect = 0.7;
  p.window_min_m = 0.3;
  const RangeModel m = range_model(p, 20.0, 0.001, 101.0);
  EXPECT_NEAR(m.sigma_m, 0.01, 1e-12);
  EXPECT_EQ(m.step_m, 0.008);
  EXPECT_EQ(m.window_max_m, 101.0);  // an unlimited window ends where the cast stopped looking
  EXPECT_EQ(range_model(p, 0.0, 0.001, 101.0).p_detect, 0.0);  // no surface, no return
}

// A halo (E8) where no surface was hit: its component is the pixel's one Gaussian, at the
// retroreflector's range with the halo's spread, and a return there is scored like any other.
TEST(RangeModel, AHaloWhereNoSurfaceWasHitIsThePixelsOnlyComponent) {
  Prediction p;
  p.p_detect = 0.3;
  p.partner_mix = 1.0;
  p.partner_offset_m = 8.0;
  p.partner_extra_variance_m2 = 0.02 * 0.02;
  p.window_min_m = 0.3;
  p.window_max_m = 100.0;
  const RangeModel m = range_model(p, 0.0, 0.001, 101.0);
  EXPECT_EQ(m.p_detect, 0.3);
  EXPECT_NEAR(m.mean_m, 8.0, 1e-12);
  EXPECT_NEAR(m.sigma_m, 0.02, 1e-12);
  EXPECT_EQ(m.partner_mix, 0.0);
  EXPECT_FALSE(score_pixel(m, 8.01, 0.5).impossible);
  EXPECT_NEAR(pixel_nll(m, 8.0), -std::log(0.3) - std::log(normal_interval(-0.025, 0.025)), 1e-9);
}

}  // namespace
}  // namespace lidartwin
