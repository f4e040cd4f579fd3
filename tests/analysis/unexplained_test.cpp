// explain_misfit and strongest_pattern on pixel tables made here, where the truth is known: a
// misfit put into some beams is traced to the beam and to nothing else, one put into an azimuth
// sector to the azimuth, a level everywhere to no feature, and a table drawn from its own
// prediction has nothing to explain.
#include "lidartwin/analysis/unexplained.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "analysis/synthetic_table.h"

namespace lidartwin {
namespace {

struct Hidden {
  double bias_on_beams_10_13_m = 0.0;
  double bias_everywhere_m = 0.0;
  double loss_in_azimuth_90_135 = 0.0;
};

// support: synthetic_table.h, with the expected signal falling as 1/r^2; the measured pixels carry
// `hidden`.
PixelTable synthetic(const Hidden& hidden) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  PixelTable t = test::synthetic_layout();
  for (size_t i = 0; i < t.size(); ++i) {
    const double ideal = static_cast<double>(t.ideal_range_m[i]);
    t.expected_signal[i] = static_cast<float>(2e5 / (ideal * ideal));
    double bias = hidden.bias_everywhere_m;
    if (t.beam[i] >= 10 && t.beam[i] <= 13) bias += hidden.bias_on_beams_10_13_m;
    std::normal_distribution<double> noise(bias, 0.02);
    const double azimuth = static_cast<double>(t.azimuth_deg[i]);
    const bool lost = azimuth >= 90 && azimuth < 135 && uniform(rng) < hidden.loss_in_azimuth_90_135;
    t.range_m[i] = lost ? 0.0f : static_cast<float>(std::round((ideal + noise(rng)) * 1000.0) / 1000.0);
  }
  return t;
}

struct Explained {
  PixelTable table;
  PixelScores scores;
  std::vector<UnexplainedMisfit> unexplained;
};
Explained explain(const Hidden& hidden) {
  Explained e{synthetic(hidden), {}, {}};
  e.scores = score_pixels(e.table);
  e.unexplained = explain_misfit(e.table, e.scores, find_misfit(e.table, e.scores, 4, {}), 0.01);
  return e;
}

const UnexplainedMisfit* of(const std::vector<UnexplainedMisfit>& all, const std::string& quantity) {
  const auto it = std::find_if(all.begin(), all.end(), [&](const auto& u) { return u.quantity == quantity; });
  return it == all.end() ? nullptr : &*it;
}

bool has(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

TEST(Unexplained, ATableDrawnFromItsOwnPredictionHasNothingToExplain) { EXPECT_TRUE(explain({}).unexplained.empty()); }

TEST(Unexplained, ABiasOnAFewBeamsFollowsTheBeamAndNothingElse) {
  const Explained e = explain({.bias_on_beams_10_13_m = 0.03});
  const UnexplainedMisfit* bias = of(e.unexplained, "bias");
  ASSERT_NE(bias, nullptr);
  EXPECT_EQ(bias->features, std::vector<std::string>{"beam"}) << bias->sentence;
  // (Incidence here is the beam number: within a beam it cannot vary, so it is not tested.)
  for (const char* other : {"range", "azimuth", "time", "signal"}) {
    EXPECT_TRUE(has(bias->not_features, other)) << other << ": " << bias->sentence;
  }
  ASSERT_FALSE(bias->regions.empty());
  for (const std::string& region : bias->regions) {
    const int b = std::stoi(region.substr(5));  // "beam 12"
    EXPECT_TRUE(b >= 10 && b <= 13) << region;
  }
  EXPECT_EQ(bias->unit, "m");
  EXPECT_NEAR(bias->size, 0.03, 0.002);
  EXPECT_NE(bias->sentence.find("varies with beam"), std::string::npos) << bias->sentence;
  // The diagnosis' pattern is the same: a bias per beam.
  const FeaturePattern pattern = strongest_pattern(e.table, e.scores);
  EXPECT_EQ(pattern.quantity, "bias");
  EXPECT_EQ(pattern.feature, "beam");
}

TEST(Unexplained, LossesInOneAzimuthSectorFollowTheAzimuth) {
  const Explained e = explain({.loss_in_azimuth_90_135 = 0.3});
  const UnexplainedMisfit* detection = of(e.unexplained, "detection");
  ASSERT_NE(detection, nullptr);
  ASSERT_FALSE(detection->features.empty());
  EXPECT_EQ(detection->features.front(), "azimuth") << detection->sentence;
  EXPECT_TRUE(has(detection->not_features, "beam")) << detection->sentence;
  EXPECT_TRUE(has(detection->not_features, "range")) << detection->sentence;
  ASSERT_EQ(detection->regions.size(), 1u) << detection->sentence;
  EXPECT_EQ(detection->regions[0], "azimuth 90–135°");
  EXPECT_NEAR(detection->size, 0.3, 0.02);
  // A loss is not a bias: nothing to say about the range where it returns.
  EXPECT_EQ(of(e.unexplained, "bias"), nullptr);
}

TEST(Unexplained, ALevelAlikeEverywhereFollowsNoFeature) {
  const Explained e = explain({.bias_everywhere_m = 0.01});
  const UnexplainedMisfit* bias = of(e.unexplained, "bias");
  ASSERT_NE(bias, nullptr);
  EXPECT_TRUE(bias->features.empty()) << bias->sentence;
  EXPECT_NE(bias->sentence.find("alike everywhere"), std::string::npos) << bias->sentence;
  EXPECT_NEAR(bias->size, 0.01, 0.001);
  // A common shift moves every bin alike: it is not read as a spread.
  EXPECT_EQ(of(e.unexplained, "spread"), nullptr);
}

// A missing effect's outliers come on top of the model's own: an edge partner's returns (E6) at
// 3 % of the pixels at depth edges, where the model expects a few outliers of its own (E2's tails,
// 1e-4), and far ranges, where it expects many (2e-3) and there are no more. Read as a factor on
// the model's rate, the edge bins' excess nearly fitted one common level (the model's rate is high
// there too) while the range bins, whose rate the excess does not follow, led; the excess is a
// share added to the model's rate, and it follows the distance to the edge first.
TEST(Unexplained, OutliersAddedAtDepthEdgesFollowTheEdgeNotWhereTheModelExpectsItsOwn) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  PixelTable t = test::synthetic_layout();
  for (size_t i = 0; i < t.size(); ++i) {
    const double ideal = static_cast<double>(t.ideal_range_m[i]);
    t.expected_signal[i] = static_cast<float>(2e5 / (ideal * ideal));
    const bool edge = t.column[i] % 8 == 0;
    if (edge) t.edge[i] = 0;
    t.outlier_mix[i] = static_cast<float>((ideal > 40.0 ? 2e-3 : 1e-6) + (edge ? 1e-4 : 0.0));
    double r = ideal + noise(rng);
    if (uniform(rng) < static_cast<double>(t.outlier_mix[i])) r = 0.3 + 100.7 * uniform(rng);
    if (edge && uniform(rng) < 0.03) r = ideal + 1.5 + noise(rng);
    t.range_m[i] = static_cast<float>(std::round(r * 1000.0) / 1000.0);
  }
  const PixelScores scores = score_pixels(t);
  const std::vector<UnexplainedMisfit> all = explain_misfit(t, scores, find_misfit(t, scores, 4, {}), 0.01);
  const UnexplainedMisfit* outliers = of(all, "outliers");
  ASSERT_NE(outliers, nullptr);
  ASSERT_FALSE(outliers->features.empty()) << outliers->sentence;
  EXPECT_EQ(outliers->features.front(), "edge") << outliers->sentence;
  EXPECT_FALSE(has(outliers->features, "range")) << outliers->sentence;
}

}  // namespace
}  // namespace lidartwin
