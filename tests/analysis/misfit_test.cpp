// find_misfit on pixel tables made here, where the truth is known: a table drawn from its own
// prediction fails nowhere; one with a wider spread in one range band fails there, in that band.
#include "lidartwin/analysis/misfit.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "analysis/synthetic_table.h"

namespace lidartwin {
namespace {

// support: synthetic_table.h; the measured spread is wider by `factor` where the ideal range lies
// in [band_lo, band_hi), and shifted by bias_m there.
PixelTable synthetic(double factor, double band_lo, double band_hi, double bias_m = 0.0) {
  std::mt19937_64 rng(7);
  PixelTable t = test::synthetic_layout();
  for (size_t i = 0; i < t.size(); ++i) {
    const double ideal = static_cast<double>(t.ideal_range_m[i]);
    const bool in_band = ideal >= band_lo && ideal < band_hi;
    std::normal_distribution<double> noise(in_band ? bias_m : 0.0, 0.02 * (in_band ? factor : 1.0));
    t.range_m[i] = static_cast<float>(std::round((ideal + noise(rng)) * 1000.0) / 1000.0);
  }
  return t;
}

TEST(Misfit, ATableDrawnFromItsOwnPredictionFailsNowhere) {
  const PixelTable t = synthetic(1.0, 0, 0);
  const Misfit m = find_misfit(t, score_pixels(t), 4, {});
  EXPECT_TRUE(m.failing.empty()) << m.failing.front().sentence;
  EXPECT_NEAR(m.summary.nll_per_pixel, m.summary.nll_expected, 4 * m.summary.nll_se);
  EXPECT_GT(m.summary.pit_uniformity_p, 1e-3);
  EXPECT_NEAR(m.summary.z_std, 1.0, 0.01);
  EXPECT_GT(m.summary.tests, 100u);
}

TEST(Misfit, AWiderSpreadInOneRangeBandIsNamedByThatBand) {
  const PixelTable t = synthetic(2.0, 20.0, 35.0);
  const Misfit m = find_misfit(t, score_pixels(t), 4, {});
  ASSERT_FALSE(m.failing.empty());
  const FailingRegion& worst = m.failing.front();
  EXPECT_EQ(worst.quantity, "spread") << worst.sentence;
  ASSERT_EQ(worst.region.size(), 1u) << worst.sentence;
  EXPECT_EQ(worst.region[0].first, "range");
  EXPECT_EQ(worst.region[0].second, (std::array<double, 2>{20.0, 35.0}));
  // Within 5 model sigma (beyond, returns count as outliers), a spread twice the model's measures
  // about 1.9 times.
  EXPECT_NEAR(worst.measured / worst.predicted, 1.9, 0.1);
  EXPECT_NE(worst.sentence.find("range 20–35 m: the measured spread is 1.9 times the model's"), std::string::npos)
      << worst.sentence;
  // Spread, and the tails it brings. Bins of other features fail too, diluted (every beam holds
  // some of the band); but no other range band does.
  for (const FailingRegion& f : m.failing) {
    EXPECT_TRUE(f.quantity == "spread" || f.quantity == "outliers") << f.sentence;
    EXPECT_LT(f.p_value, 0.01);
    EXPECT_LT(f.misfit_per_pixel, worst.misfit_per_pixel * 1.0001) << f.sentence;
    for (const auto& [name, range] : f.region) {
      if (name == "range") {
        EXPECT_EQ(range, (std::array<double, 2>{20.0, 35.0})) << f.sentence;
      }
    }
  }
  EXPECT_GT(m.summary.nll_per_pixel, m.summary.nll_expected + 10 * m.summary.nll_se);
}

TEST(Misfit, ABiasInOneBandIsNamedWithItsSignAndSize) {
  const PixelTable t = synthetic(1.0, 8.0, 13.0, -0.03);
  const Misfit m = find_misfit(t, score_pixels(t), 4, {});
  ASSERT_FALSE(m.failing.empty());
  const FailingRegion& worst = m.failing.front();
  EXPECT_EQ(worst.quantity, "bias") << worst.sentence;
  EXPECT_EQ(describe(worst.region), "range 8–13 m");
  EXPECT_NEAR(worst.measured, -0.03, 0.002);
  EXPECT_NE(worst.sentence.find("30 mm shorter than the model's"), std::string::npos) << worst.sentence;
}

TEST(Misfit, MissesWhereTheModelIsCertainFailDetection) {
  PixelTable t = synthetic(1.0, 0, 0);
  for (size_t i = 0; i < t.size(); ++i) {
    if (t.beam[i] == 5 && i % 3 == 0) t.range_m[i] = 0.0f;  // a third of beam 5 goes missing
  }
  const Misfit m = find_misfit(t, score_pixels(t), 4, {});
  ASSERT_FALSE(m.failing.empty());
  EXPECT_EQ(m.failing.front().quantity, "detection");
  EXPECT_EQ(describe(m.failing.front().region), "beam 5");
  EXPECT_GT(m.summary.impossible_misses, 0u);
}

// The spread wider by `factor` in one azimuth band (columns 0-63: 315-360 degrees), and, when given,
// only where the ideal range also lies in [range_lo, range_hi).
PixelTable wider_in_azimuth(double factor, double range_lo = 0.0, double range_hi = 1e3) {
  std::mt19937_64 rng(11);
  PixelTable t = test::synthetic_layout();
  for (size_t i = 0; i < t.size(); ++i) {
    const double ideal = static_cast<double>(t.ideal_range_m[i]);
    const bool wider = t.column[i] < 64 && ideal >= range_lo && ideal < range_hi;
    std::normal_distribution<double> noise(0.0, 0.02 * (wider ? factor : 1.0));
    t.range_m[i] = static_cast<float>(std::round((ideal + noise(rng)) * 1000.0) / 1000.0);
  }
  return t;
}

bool names(const FailingRegion& f, const std::string& feature) {
  return std::ranges::any_of(f.region, [&](const auto& r) { return r.first == feature; });
}

TEST(Misfit, ThePairsOfAFailingFeatureThatOnlyShareItsMisfitAreNotRegionsOfTheirOwn) {
  // A spread 6 % wide over all of azimuth 315-360 degrees: its pair bins (that azimuth band at
  // each range) carry the same 6 %, each measured on an eighth of the pixels, so some read twice
  // the misfit per pixel by chance; none departs from the band's own spread beyond chance.
  const PixelTable t = wider_in_azimuth(1.06);
  const Misfit m = find_misfit(t, score_pixels(t), 4, {});
  ASSERT_FALSE(m.failing.empty());
  EXPECT_EQ(describe(m.failing.front().region), "azimuth 315–360°") << m.failing.front().sentence;
  for (const FailingRegion& f : m.failing) {
    EXPECT_FALSE(f.region.size() == 2 && names(f, "azimuth")) << f.sentence;
  }
}

TEST(Misfit, APairThatFailsBeyondItsFeaturesIsARegionOfItsOwn) {
  // Wider only at range 20-35 m within azimuth 315-360 degrees: the pair is the misfit's place and
  // leads; the azimuth band alone fails diluted.
  const PixelTable t = wider_in_azimuth(1.5, 20.0, 35.0);
  const Misfit m = find_misfit(t, score_pixels(t), 4, {});
  ASSERT_FALSE(m.failing.empty());
  const FailingRegion& worst = m.failing.front();
  EXPECT_EQ(worst.quantity, "spread") << worst.sentence;
  ASSERT_EQ(worst.region.size(), 2u) << worst.sentence;
  EXPECT_TRUE(names(worst, "azimuth") && names(worst, "range")) << worst.sentence;
  EXPECT_NEAR(worst.measured / worst.predicted, 1.5, 0.05) << worst.sentence;
}

}  // namespace
}  // namespace lidartwin
