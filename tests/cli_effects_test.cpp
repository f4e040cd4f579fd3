// `lidartwin effects`: every registered effect listed with its catalogue id, prerequisites and
// parameters (defaults and bounds as the effect itself reports them); --json for scripts.
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"

namespace cli_effects_test {

namespace {

using lidartwin::test::run_cli;

const nlohmann::json* find(const nlohmann::json& list, const std::string& key, const std::string& value) {
  for (const nlohmann::json& e : list) {
    if (e.value(key, "") == value) return &e;
  }
  return nullptr;
}

TEST(CliEffects, JsonListsEveryEffectWithItsParametersDefaultsAndBounds) {
  const auto run = run_cli("effects --json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json effects = nlohmann::json::parse(run.output);
  ASSERT_TRUE(effects.is_array());
  for (const char* name : {"radiometry", "range_noise_linear", "dropout", "mixed_pixels", "window", "fog",
                           "false_alarms", "shot_noise", "range_limits"}) {
    EXPECT_NE(find(effects, "name", name), nullptr) << name << "\n" << run.output;
  }
  const nlohmann::json* window = find(effects, "name", "window");
  ASSERT_NE(window, nullptr);
  EXPECT_EQ((*window)["catalogue"], "E16");
  EXPECT_EQ((*window)["prerequisites"], nlohmann::json::array({"radiometry"}));
  const nlohmann::json* width = find((*window)["parameters"], "name", "sector_width_deg");
  ASSERT_NE(width, nullptr);
  EXPECT_EQ((*width)["default"], 30.0);
  EXPECT_EQ((*width)["lower"], 0.0);
  EXPECT_EQ((*width)["upper"], 360.0);
  EXPECT_EQ((*find(effects, "name", "fog"))["catalogue"], "E13");
  EXPECT_EQ((*find(effects, "name", "radiometry"))["prerequisites"], nlohmann::json::array());
  // The paper's sigma(r) has no defaults: the listing says what it needs instead of inventing values.
  const nlohmann::json* linear = find(effects, "name", "range_noise_linear");
  ASSERT_NE(linear, nullptr);
  ASSERT_TRUE(linear->contains("requires")) << linear->dump();
  EXPECT_EQ((*linear)["requires"], "sigma0_m: missing; range_noise_linear needs it, a number in [0, 1]")
      << linear->dump();
}

TEST(CliEffects, TableShowsCatalogueIdsAndParameterLines) {
  const auto run = run_cli("effects");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("false_alarms (E14)\n    after: radiometry\n"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("    attenuation_per_m            0.06           in [0, 1]\n"), std::string::npos)
      << run.output;
}

// Two effects share E16 and two have no id (issue 24): the listing says which part each models.
TEST(CliEffects, TableSaysWhichPartOfACatalogueEntryAnEffectModels) {
  const auto run = run_cli("effects");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("range_limits (E16)\n    E16's near-range part"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("window (E16)\n    E16's window part"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("shot_noise\n    no catalogue id: lidar-physics.md 2.2"), std::string::npos) << run.output;
}

// points' help describes the array it writes: xyz is flat (3 floats a point), not N x 3.
TEST(CliEffects, PointsHelpDescribesTheFlatXyzArray) {
  const auto run = run_cli("points --help");
  EXPECT_NE(run.output.find("xyz (flat, x y z of each point in turn: reshape(-1, 3); m)"), std::string::npos)
      << run.output;
}

}  // namespace

}  // namespace cli_effects_test
