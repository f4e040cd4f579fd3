// The failing regions as the report leads with them: neighbouring bins merged, ranked by the misfit
// they explain, materials by the scene's names (issue 24: "beams 40, 41, 42, 43 and 44 are five
// rows"; "material 48" though the scene names it).
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

// Every incidence bin failing, merged, holds all the pixels and the most misfit, but says nothing
// of where the model fails: the run that localizes it comes first.
TEST(FailingRuns, ARunOverMostOfItsFeatureComesAfterThoseThatLocalizeTheMisfit) {
  Misfit misfit;
  for (const auto& [lo, hi] : {std::pair{0.0, 30.0}, {30.0, 45.0}, {45.0, 60.0}, {60.0, 75.0}, {75.0, 90.0}}) {
    misfit.failing.push_back(bias("incidence", lo, hi, 0.004, 300.0));
    misfit.bins.push_back({{{"incidence", {lo, hi}}}, 1000});
  }
  misfit.failing.push_back(bias("range", 13, 20, 0.006, 800.0));
  for (int lower : {0, 13, 20}) misfit.bins.push_back({{{"range", {static_cast<double>(lower), lower + 7.0}}}, 1000});
  const std::vector<FailingRun> runs = failing_runs(misfit, {});
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].where, "range 13–20 m");  // 800 nats in a third of the pixels
  EXPECT_EQ(runs[1].region.front().first, "incidence");
  EXPECT_EQ(runs[1].bins, 5u);
  EXPECT_DOUBLE_EQ(runs[1].misfit_nats, 1500.0);
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

}  // namespace
}  // namespace lidartwin
