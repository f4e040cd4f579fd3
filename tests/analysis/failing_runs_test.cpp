// The failing regions as the report leads with them: neighbouring bins merged, ranked by the misfit
// their feature explains, with how it changes along them, materials by the scene's names (issue 24: "beams 40, 41, 42,
// 43 and 44 are five rows"; "material 48" though the scene names it).
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/analysis/compare_report.h"

namespace lidartwin {
namespace {

FailingRegion bias(const std::string& feature, double lo, double hi, double measured_m, double nats) {
  FailingRegion f;
  f.quantity = "bias";
  f.region = {{feature, {lo, hi}}};
  f.measured = measured_m;
  f.predicted = 0.0;
  f.pixels = 1000;
  f.p_value = 1e-9;
  f.misfit_nats = nats;
  f.misfit_per_pixel = nats / 1000;
  f.sentence = describe(f.region) + ": the measured range is ...";
  return f;
}

TEST(FailingRuns, NeighbouringBinsFailingAlikeAreOneRunRankedByTheirTotalMisfit) {
  Misfit misfit;
  for (int beam = 40; beam <= 44; ++beam) misfit.failing.push_back(bias("beam", beam, beam, 0.004, 100.0));
  misfit.failing.push_back(bias("beam", 45, 45, -0.004, 100.0));  // the other way: a run of its own
  misfit.failing.push_back(bias("beam", 47, 47, 0.004, 100.0));   // not a neighbour
  misfit.failing.push_back(bias("range", 13, 20, 0.003, 150.0));
  misfit.failing.push_back(bias("range", 20, 35, 0.005, 150.0));
  misfit.failing.push_back(bias("time", 0.0, 0.4, 0.02, 450.0));  // the worst bin, but less in total
  const std::vector<FailingRun> runs = failing_runs(misfit, {});
  ASSERT_EQ(runs.size(), 5u);
  EXPECT_EQ(runs[0].where, "beams 40–44");
  EXPECT_EQ(runs[0].bins, 5u);
  EXPECT_EQ(runs[0].pixels, 5000u);
  EXPECT_DOUBLE_EQ(runs[0].misfit_nats, 500.0);
  EXPECT_EQ(runs[0].sentence,
            "beams 40–44: the measured range is 4.0 mm longer than the model's (5 bins, 5000 pixels)");
  EXPECT_EQ(runs[1].where, "time 0.00–0.40 s");
  EXPECT_EQ(runs[2].where, "range 13–35 m");
  EXPECT_EQ(runs[2].sentence,
            "range 13–35 m: the measured range is 3.0–5.0 mm longer than the model's (2 bins, 2000 pixels)");
  EXPECT_EQ(runs[3].where, "beam 45");
  EXPECT_EQ(runs[4].where, "beam 47");
}

// A spread ratio whose misfit grows as it falls (0.7, 0.55, 0.4 times the model's) falls in words:
// "rising with the expected signal from 0.7 times ... to 0.4 times" contradicted itself.
TEST(FailingRuns, ATrendRisesOrFallsAsItsValuesRead) {
  Misfit misfit;
  const double edges[] = {0.0, 10.0, 30.0, 100.0};
  const double ratios[] = {0.7, 0.55, 0.4};
  for (size_t k = 0; k < 3; ++k) {
    FailingRegion f = bias("signal", edges[k], edges[k + 1], 0.0, 100.0 + 50.0 * static_cast<double>(k));
    f.quantity = "spread";
    f.measured = 0.01 * ratios[k];
    f.predicted = 0.01;
    misfit.failing.push_back(f);
  }
  const std::vector<FailingRun> runs = failing_runs(misfit, {});
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].trend, "falling with the expected signal");
  EXPECT_NE(runs[0].sentence.find("falling with the expected signal from 0.7 times at expected signal below 10 "
                                  "photons to 0.4 times at expected signal 30–100 photons"),
            std::string::npos)
      << runs[0].sentence;
}

// A bin of `n` inliers whose mean z is `z`, `bias_m` longer than the model: its misfit (n z^2 / 2)
// in misfit.bins, and a failing region.
void add_bias_bin(Misfit& misfit, const std::string& feature, double lo, double hi, size_t n, double z, double bias_m) {
  BinMisfit b;
  b.region = {{feature, {lo, hi}}};
  b.pixels = b.returns = b.inliers = n;
  b.bias_measured_m = bias_m;
  b.misfit_bias = static_cast<double>(n) * z * z / 2.0;
  misfit.bins.push_back(b);
  FailingRegion f = bias(feature, lo, hi, bias_m, b.misfit_bias);
  f.pixels = n;
  misfit.failing.push_back(f);
}

// A hidden warm-up drift makes every material's range 7 mm long alike, and each material carries
// more misfit than the time bins in total, yet the materials say nothing of the cause: the time
// bins, falling from 16 mm to 1 mm, do. They come first, merged, with their trend; the verdict
// quotes it.
TEST(FailingRuns, AMisfitEveryBinOfAFeatureSharesComesAfterOneThatChangesAlongItsFeature) {
  Misfit misfit;
  for (int material = 0; material < 3; ++material)
    add_bias_bin(misfit, "material", material, material, 300000, 0.3, 0.007);
  const double z[] = {0.8, 0.4, 0.2, 0.1, 0.05};
  for (int k = 0; k < 5; ++k) add_bias_bin(misfit, "time", 0.4 * k, 0.4 * (k + 1), 60000, z[k], 0.02 * z[k]);
  const std::vector<FailingRun> runs = failing_runs(misfit, {"floor", "wall", "ceiling"});
  ASSERT_EQ(runs.size(), 4u);
  EXPECT_EQ(runs[0].where, "time 0.00–2.00 s");
  EXPECT_GT(runs[1].misfit_nats, 0.5 * runs[0].misfit_nats) << "each material's misfit rivals the time run's";
  EXPECT_NEAR(runs[0].localized_nats, 11160.0, 1.0);  // 60000/2 * sum (z - 0.31)^2
  EXPECT_NEAR(runs[1].localized_nats, 0.0, 1e-6);
  EXPECT_EQ(runs[0].trend, "falling with time");
  EXPECT_EQ(runs[0].sentence,
            "time 0.00–2.00 s: the measured range is 1.0–16 mm longer than the model's, falling with time from 16 mm "
            "at time 0.00–0.40 s to 1.0 mm at time 1.60–2.00 s (5 bins, 300000 pixels)");
}

// A run that peaks inside says where; one that is flat says nothing more than its span.
TEST(FailingRuns, ARunThatPeaksInsideSaysWhereAndAFlatOneHasNoTrend) {
  Misfit misfit;
  const double peaked[] = {0.1, 0.2, 0.9, 0.2}, flat[] = {0.30, 0.31, 0.32, 0.30};
  for (int k = 0; k < 4; ++k)
    add_bias_bin(misfit, "incidence", 15.0 * k, 15.0 * (k + 1), 1000, peaked[k], 0.01 * peaked[k]);
  for (int k = 0; k < 4; ++k) add_bias_bin(misfit, "beam", k, k, 1000, flat[k], 0.01 * flat[k]);
  const std::vector<FailingRun> runs = failing_runs(misfit, {});
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].trend, "most at incidence 30–45°");
  EXPECT_NE(runs[0].sentence.find("most at incidence 30–45° (9.0 mm)"), std::string::npos) << runs[0].sentence;
  EXPECT_EQ(runs[1].where, "everywhere (beams 0–3)");  // every beam tested fails alike: no place
  EXPECT_EQ(runs[1].trend, "");
}

TEST(FailingRuns, MaterialsAreNamedAsTheSceneNamesThemAndNeverMerged) {
  Misfit misfit;
  misfit.failing.push_back(bias("material", 2, 2, 0.01, 20.0));
  misfit.failing.push_back(bias("material", 3, 3, 0.01, 10.0));
  const std::vector<FailingRun> runs = failing_runs(misfit, {"", "floor", "wall_grey", ""});
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].where, "material wall_grey (2)");
  EXPECT_EQ(runs[0].sentence, "material wall_grey (2): the measured range is ...");
  EXPECT_EQ(runs[1].where, "material 3");  // unnamed in the scene
}

// A run over every tested bin of its feature names no place: "azimuth 0–360°" reads as where the
// model fails, when it fails everywhere along the azimuth.
TEST(FailingRuns, ARunOverEveryTestedBinOfItsFeatureIsNamedEverywhere) {
  Misfit misfit;
  for (int k = 0; k < 8; ++k) add_bias_bin(misfit, "azimuth", 45.0 * k, 45.0 * (k + 1), 1000, 0.3, 0.002);
  for (int k = 0; k < 3; ++k) add_bias_bin(misfit, "range", k, k + 1, 1000, 0.3, 0.002);
  BinMisfit far;  // range 3-4 m is tested but does not fail: the range run is a place
  far.region = {{"range", {3.0, 4.0}}};
  far.pixels = far.returns = far.inliers = 1000;
  misfit.bins.push_back(far);
  const std::vector<FailingRun> runs = failing_runs(misfit, {});
  ASSERT_EQ(runs.size(), 2u);
  for (const FailingRun& run : runs) {
    if (run.region.front().first == "azimuth") {
      EXPECT_TRUE(run.everywhere);
      EXPECT_EQ(run.where.rfind("everywhere (azimuth ", 0), 0u) << run.where;
      EXPECT_EQ(run.sentence.rfind(run.where + ": ", 0), 0u) << run.sentence;
    } else {
      EXPECT_FALSE(run.everywhere) << run.where;
      EXPECT_EQ(run.where, "range below 3 m");
    }
  }
}

}  // namespace
}  // namespace lidartwin
