#pragma once
// What a misfit no library effect explains follows (lidar-physics.md 3.2, 3.4): for each quantity
// that still fails (bias, spread, detection, outliers), the features of the compare vocabulary its
// residual varies with, found by forward selection: the feature whose bins differ most (a
// chi-square test of heterogeneity between bins) first, then each further feature tested within
// the bins of those already chosen, so one that only rides along with a chosen one (signal with
// range) is not named. What it does not depend on is said as well: that is what tells a user which
// kind of effect to write ("the bias follows material and does not depend on range or beam").
#include <cstddef>
#include <string>
#include <vector>

#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/pixel_table.h"
#include "lidartwin/effects/measurement.h"

namespace lidartwin {

struct FeatureTest {
  std::string feature;
  double chi2 = 0.0;  // heterogeneity between its bins, within the bins of the features chosen before
  double dof = 0.0;
  double p_value = 1.0;  // corrected for the number of tests
};

struct UnexplainedMisfit {
  std::string quantity;                   // bias, spread, detection, outliers
  std::vector<std::string> features;      // what it follows, strongest first; empty: alike everywhere
  std::vector<std::string> not_features;  // tested, and not followed given those
  std::vector<FeatureTest> tests;         // the chosen features' tests, then the last round's others
  double size = 0.0;                      // largest |measured - model| over the first feature's bins
  std::string unit;                       // of size: "m" (bias), "ratio" (spread), "fraction"
  std::vector<std::string> regions;       // the first feature's worst bins, described
  std::string sentence;
};

// table/scores: the pixels under the final chain; misfit: find_misfit's result on them, whose
// failing regions say which quantities still fail. alpha: the level of every test, corrected.
std::vector<UnexplainedMisfit> explain_misfit(const PixelTable& table, const PixelScores& scores, const Misfit& misfit,
                                              double alpha);

// The strongest pattern of the model's misfit along one feature: what a free adjustment per bin of
// that feature (a bias, a spread factor, a detection or outlier rate per bin) would gain, as a
// likelihood-ratio statistic (chi2 ~ 2 delta NLL; counts by the G statistic, probabilities kept
// off 0 and 1 as the pixel likelihood keeps them) with dof free values, the largest by its BIC
// (chi2 - dof ln n). The diagnosis weighs a library candidate against it: a
// candidate that gains less than a per-bin pattern is only absorbing part of an effect it is not.
struct FeaturePattern {
  std::string quantity;  // empty: none gains anything
  std::string feature;
  double chi2 = 0.0;
  double dof = 0.0;
  size_t pixels = 0;  // pixels of that quantity (n)
};
FeaturePattern strongest_pattern(const PixelTable& table, const PixelScores& scores);

// misfit.causes from explain_misfit: what each failing quantity follows and what rides along, so
// that the failing runs lead with the cause (failing_runs).
void find_causes(const PixelTable& table, const PixelScores& scores, Misfit& misfit, double alpha);

// That pattern as an adjustment of the chain's predictions: a free value per bin of its feature,
// fitted in closed form on the table (a bias shift in metres, a variance factor, a factor on the
// detection probability, an added outlier share). The diagnosis adds it to ask whether a library
// candidate still gains once the pattern is explained.
struct PatternAdjustment {
  std::string quantity;
  enum class Target { kBias, kSpread, kDetection, kOutliers };
  Target target = Target::kBias;  // the quantity, decided once: apply() runs per pixel per fit step
  std::vector<int16_t> bin;       // per pixel of the table (-1: left alone)
  std::vector<double> value;      // per bin
  void apply(size_t pixel, Prediction& prediction) const;
};
PatternAdjustment pattern_adjustment(const PixelTable& table, const PixelScores& scores, const FeaturePattern& pattern);

}  // namespace lidartwin
