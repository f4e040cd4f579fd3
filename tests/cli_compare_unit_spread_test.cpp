// A unit whose range noise is tighter than its profile's, as a second unit of a product often is:
// compare says so plainly, with how far the profile says units differ, and --diagnose refits the
// unit's own noise law, its next command (`fit --auto --refit-noise`) making a twin of the unit that
// fits frames the fit never saw.
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"

namespace cli_compare_unit_spread_test {

namespace fs = std::filesystem;

namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;

using lidartwin::test::CliRun;
using lidartwin::test::run_cli;

nlohmann::json read_json(const fs::path& path) { return nlohmann::json::parse(std::ifstream(path)); }

// os0-32 with its datasheet table's sigmas and E2's k at half: a unit half as noisy as the one the
// profile was fitted on (units of the OS0 line are known to differ so: the profile's unit_to_unit).
fs::path tighter_unit(const fs::path& dir) {
  nlohmann::json profile = read_json(kSource + "/profiles/os0-32.json");
  for (auto& effect : profile["effects"]) {
    if (effect["name"] == "range_noise_piecewise") {
      for (auto& point : effect["points_m"]) point[1] = point[1].get<double>() * 0.5;
    }
    if (effect["name"] == "signal_precision") effect["k_m"] = effect["k_m"].get<double>() * 0.5;
  }
  const fs::path path = dir / "tighter-os0-32.json";
  std::ofstream(path) << profile.dump(1);
  return path;
}

TEST(CompareUnitSpread, AUnitTighterThanItsProfileIsSaidSoAndItsOwnNoiseIsTheNextFit) {
  const fs::path dir = fs::path(testing::TempDir()) / ("unit_spread_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string hall = kSource + "/scenes/calibration_hall.glb";
  const CliRun recorded =
      run_cli("record --profile " + tighter_unit(dir).string() + " --scene " + hall + " --trajectory " + kSource +
              "/scenes/calibration_hall_static.tum --frames 4 --seed 31 --out " + (dir / "capture").string());
  ASSERT_EQ(recorded.exit_code, 0) << recorded.output;
  const std::string inputs = " --capture " + (dir / "capture").string() + " --scene " + hall;

  // Without --diagnose: said, and pointed at the diagnosis.
  const CliRun plain =
      run_cli("compare" + inputs + " --frames 2 --no-plots --profile os0-32 --out " + (dir / "plain").string());
  ASSERT_EQ(plain.exit_code, 0) << plain.output;
  const std::string verdict = read_json(dir / "plain" / "report.json")["verdict_sentence"];
  std::printf("  %s\n", verdict.c_str());
  // (0.76, not 0.5: E4's footprint spread, the same in both, is not halved.)
  EXPECT_NE(verdict.find("This unit's range noise is tighter than the profile's: its spread is 0.7"), std::string::npos)
      << verdict;
  EXPECT_NE(verdict.find("within the 2x by which units of the OS-0-32-U1 are known to differ"), std::string::npos)
      << verdict;
  EXPECT_NE(verdict.find("run the same compare with --diagnose to fit this unit's own noise"), std::string::npos)
      << verdict;
  EXPECT_NE(plain.output.find(verdict), std::string::npos) << "the terminal says it too";

  // With it: the law's sigmas refitted, and the next command makes the twin.
  const CliRun diagnosed = run_cli("compare" + inputs + " --frames 2 --no-plots --diagnose --profile os0-32 --out " +
                                   (dir / "diagnosed").string());
  ASSERT_EQ(diagnosed.exit_code, 0) << diagnosed.output;
  const nlohmann::json report = read_json(dir / "diagnosed" / "report.json");
  const std::string next = report["verdict_sentence"];
  const size_t at = next.find("run `lidartwin fit ");
  ASSERT_NE(at, std::string::npos) << next;
  const std::string command = next.substr(at + 5, next.rfind('`') - at - 5);
  EXPECT_NE(command.find("--refit-noise"), std::string::npos) << command;
  bool refitted_law = false;
  for (const auto& m : report["diagnosis"]["parameter_misfit"]) {
    refitted_law = refitted_law || m["effect"] == "range_noise_piecewise";
  }
  EXPECT_TRUE(refitted_law) << report["diagnosis"]["parameter_misfit"].dump(1);

  // The command as given, then the twin judged on the two frames it never saw.
  const std::string fit = command.substr(std::string("lidartwin ").size());
  const CliRun twin = run_cli(fit);
  ASSERT_EQ(twin.exit_code, 0) << twin.output;
  const fs::path fitted = dir / "diagnosed" / "fitted.json";
  ASSERT_TRUE(fs::exists(fitted)) << command;
  const CliRun held = run_cli("compare" + inputs + " --skip-frames 2 --no-plots --profile os0-32 --profile " +
                              fitted.string() + " --out " + (dir / "held").string());
  ASSERT_EQ(held.exit_code, 0) << held.output;
  const nlohmann::json waterfall = read_json(dir / "held" / "report.json")["waterfall"];
  ASSERT_EQ(waterfall.size(), 2u);
  std::printf("  held out: os0-32 %d failing regions, the twin %d\n", waterfall[0]["failing_regions"].get<int>(),
              waterfall[1]["failing_regions"].get<int>());
  EXPECT_GT(waterfall[0]["failing_regions"].get<int>(), 0);
  EXPECT_LT(waterfall[1]["nll_per_pixel"].get<double>(), waterfall[0]["nll_per_pixel"].get<double>());
  const std::string twin_verdict = read_json(dir / "held" / "report.json")["verdict_sentence"];
  EXPECT_EQ(twin_verdict.find("tighter than the profile's"), std::string::npos) << twin_verdict;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace cli_compare_unit_spread_test
