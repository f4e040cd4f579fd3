// A profile whose range noise has the wrong form (issue 23), as `compare --diagnose` and `fit` see
// it: the diagnosis must say the law is to be replaced (diagnosis.replace), not add effects on top
// of it, and `fit` applying the replacement must fit held-out frames.
//  - The independent generator's room with a spread that follows E2's SNR law alone (a floor and
//    k, no sigma(r)), against the paper's linear law: replaced by signal_precision, k and the floor
//    covering the generator's.
//  - A hall recording of os1-64 (the datasheet table, incidence), against os1-32-paper (the linear
//    law, no incidence): replaced by the datasheet table, and incidence added.
//  - The reverse: the generator's linear law against the datasheet table.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"
#include "support/table_profile.h"

namespace lidartwin::cli_compare_noise_law_test {
namespace {

namespace fs = std::filesystem;
using test::run_cli;

const std::string kSource = LIDARTWIN_SOURCE_DIR;

nlohmann::json read_json(const fs::path& path) { return nlohmann::json::parse(std::ifstream(path)); }

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(testing::TempDir()) / ("noise_law_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The independent generator's room in `dir` with `args`, and compare's inputs for it.
std::string generated_room(const fs::path& dir, const std::string& args) {
  EXPECT_EQ(std::system(("/usr/bin/python3 " + kSource + "/tests/tools/independent_capture.py " + dir.string() + " " +
                         args + " > /dev/null")
                            .c_str()),
            0)
      << args;
  return " --capture " + (dir / "capture.pcap").string() + " --metadata " + (dir / "metadata.json").string() +
         " --scene " + (dir / "scene.gltf").string() + " --pose " + (dir / "pose.tum").string();
}

void expect_covers(const nlohmann::json& params, const std::string& name, double truth) {
  ASSERT_TRUE(params.contains(name)) << params.dump(1);
  const auto& p = params[name];
  std::printf("  %s: %.6g [%.6g, %.6g], truth %.6g\n", name.c_str(), p["value"].get<double>(),
              p["ci95"][0].get<double>(), p["ci95"][1].get<double>(), truth);
  EXPECT_LE(p["ci95"][0].get<double>(), truth) << name << ": " << p.dump();
  EXPECT_GE(p["ci95"][1].get<double>(), truth) << name << ": " << p.dump();
}

// Each fitted parameter has a robust (sandwich) interval beside the curvature's. With the right
// model and independent pixels the two agree to within a factor 1.5 either way (the information
// equality); beside a wrong noise law the robust one is the wider (min_ratio).
void expect_robust_intervals(const nlohmann::json& selected, double min_ratio = 1 / 1.5, double max_ratio = 1.5) {
  for (const auto& c : selected) {
    for (const auto& [name, p] : c["params"].items()) {
      ASSERT_TRUE(p.contains("ci95_robust")) << name << ": " << p.dump();
      const double width = p["ci95"][1].get<double>() - p["ci95"][0].get<double>();
      const double robust = p["ci95_robust"][1].get<double>() - p["ci95_robust"][0].get<double>();
      EXPECT_LE(p["ci95_robust"][0].get<double>(), p["value"].get<double>()) << name;
      EXPECT_GE(p["ci95_robust"][1].get<double>(), p["value"].get<double>()) << name;
      EXPECT_GT(robust, width * min_ratio) << name << ": " << p.dump();
      EXPECT_LT(robust, width * max_ratio) << name << ": " << p.dump();
    }
  }
}

double excess_se(const nlohmann::json& step) {
  return (step["nll_per_pixel"].get<double>() - step["nll_expected"].get<double>()) / step["nll_se"].get<double>();
}

// The profile `fitted` against `base` on the frames after the first `fit_frames` (held out from the
// fit): the base misfits them, the fitted profile scores what its own model expects, and no region
// fails.
void expect_held_out_fit(const std::string& inputs, const std::string& base, const fs::path& fitted, int fit_frames,
                         const fs::path& out) {
  const test::CliRun r =
      run_cli("compare" + inputs + " --skip-frames " + std::to_string(fit_frames) + " --no-plots --profile " + base +
              " --profile " + fitted.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json waterfall = read_json(out / "report.json")["waterfall"];
  ASSERT_EQ(waterfall.size(), 2u) << waterfall.dump(1);
  const auto& before = waterfall[0];
  const auto& after = waterfall[1];
  std::printf("  held-out NLL/pixel: %s %.4f (%+.1f SE), fitted %.4f (%+.1f SE), expected %.4f; %d regions fail\n",
              before["profile"].get<std::string>().c_str(), before["nll_per_pixel"].get<double>(), excess_se(before),
              after["nll_per_pixel"].get<double>(), excess_se(after), after["nll_expected"].get<double>(),
              after["failing_regions"].get<int>());
  EXPECT_GT(std::abs(excess_se(before)), 5.0);
  EXPECT_LT(std::abs(excess_se(after)), 4.0);
  EXPECT_EQ(after["failing_regions"], 0);
}

// E2 alone: sigma^2 = floor^2 + k^2 (S + B) / S^2 with a 3 mm floor and k = 0.3 m sqrt(photon),
// which over the room's ranges (5-14 m, 130-1900 photons) makes a spread of 7-28 mm, at least twice
// the floor everywhere. The paper's 10 mm + 1.4 mm/m is wrong in form, not in its values: no
// effect added on top of it can lower the spread where the signal is strong.
TEST(CompareNoiseLaw, ASpreadThatFollowsTheSignalAloneReplacesTheLinearLawBySignalPrecision) {
  const fs::path dir = fresh_dir("e2");
  const std::string inputs = generated_room(dir, "--frames 5 --seed 2 --sigma0 0.003 --slope 0 --snr-k 0.3");
  const nlohmann::json truth = read_json(dir / "truth.json");
  const test::CliRun r =
      run_cli("compare" + inputs + " --frames 3 --no-plots --diagnose --profile os1-32-paper --out " +
              (dir / "report").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("replace: range_noise_linear (E1) has the wrong form: signal_precision (E2)"),
            std::string::npos)
      << r.output;
  const nlohmann::json d = read_json(dir / "report" / "report.json")["diagnosis"];
  ASSERT_EQ(d["replace"].size(), 1u) << d.dump(1);
  const auto& replace = d["replace"][0];
  EXPECT_EQ(replace["effect"], "range_noise_linear");
  EXPECT_EQ(replace["replacement"]["effect"], "signal_precision");
  EXPECT_EQ(replace["parameters"]["added"], 2);
  std::printf("  delta BIC %.0f, %.0f over the best additive explanation (%s)\n", replace["delta_bic"].get<double>(),
              replace["delta_bic_vs_additive"].get<double>(), replace["additive"].dump().c_str());
  EXPECT_GT(replace["delta_bic_vs_additive"].get<double>(), 10.0);
  expect_covers(replace["replacement"]["params"], "k_m", truth["snr_k_m"].get<double>());
  expect_covers(replace["replacement"]["params"], "floor_m", truth["range_noise"]["sigma0_m"].get<double>());
  // Nothing else is missing once the law is right.
  EXPECT_TRUE(d["selected"].empty()) << d["selected"].dump(1);
  EXPECT_TRUE(d["unexplained"].empty()) << d["unexplained"].dump(1);
  EXPECT_EQ(d["verdict"], "wrong effect form");

  // fit --auto applies what the diagnosis says, on the same frames; the two held out are fitted.
  const fs::path fitted = dir / "fitted.json";
  const test::CliRun fit =
      run_cli("fit" + inputs + " --frames 3 --profile os1-32-paper --auto --out " + fitted.string());
  ASSERT_EQ(fit.exit_code, 0) << fit.output;
  std::printf("%s", fit.output.c_str());
  const nlohmann::json profile = read_json(fitted);
  bool e2 = false;
  for (const auto& effect : profile["effects"]) {
    EXPECT_NE(effect["name"], "range_noise_linear") << effect;
    e2 = e2 || effect["name"] == "signal_precision";
  }
  EXPECT_TRUE(e2) << profile["effects"].dump(1);
  bool noted = false;  // the "fit" section says what was replaced
  for (const auto& note : profile["fit"]["effects"])
    noted = noted || note.value("replaces", "") == "range_noise_linear";
  EXPECT_TRUE(noted) << profile["fit"].dump(1);
  expect_held_out_fit(inputs, "os1-32-paper", fitted, 3, dir / "held_out");
  fs::remove_all(dir);
}

// os1-64 as the datasheet gives it (the table, incidence at its beam divergence, signal-driven
// dropout; without what real captures added since, E2 and E6: datasheet_only_profile) recorded in the hall and compared
// with the paper's OS1 profile (the linear law, neither of the others): the law is replaced by the datasheet table
// (OS1's, from the shipped profiles) with its sigmas where the hall has ranges (10 mm from 1 to 20 m), and the
// incidence and dropout the paper's profile lacks are added. `fit --replace`, with them added, fits the held-out
// frames.
TEST(CompareNoiseLaw, ADatasheetCaptureAgainstTheLinearLawReplacesItByTheTableAndAddsIncidence) {
  const fs::path dir = fresh_dir("os1_64");
  const std::string hall = kSource + "/scenes/calibration_hall.glb";
  const test::CliRun recorded =
      run_cli("record --profile " + table_profiles::datasheet_only_profile("os1-64").string() + " --scene " + hall +
              " --trajectory " + kSource + "/scenes/calibration_hall_static.tum --frames 4 --seed 11 --out " +
              (dir / "capture").string());
  ASSERT_EQ(recorded.exit_code, 0) << recorded.output;
  const nlohmann::json os1_64 = read_json(kSource + "/profiles/os1-64.json");
  double divergence = 0.0;
  for (const auto& effect : os1_64["effects"]) {
    if (effect["name"] == "incidence") divergence = effect["divergence_rad"];
  }
  ASSERT_GT(divergence, 0.0);
  const std::string inputs = " --capture " + (dir / "capture").string() + " --scene " + hall;
  const test::CliRun r =
      run_cli("compare" + inputs + " --frames 2 --no-plots --diagnose --profile os1-32-paper --out " +
              (dir / "report").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::printf("%s", r.output.substr(r.output.find("diagnosis on")).c_str());
  const nlohmann::json d = read_json(dir / "report" / "report.json")["diagnosis"];
  ASSERT_EQ(d["replace"].size(), 1u) << d.dump(1);
  const auto& replace = d["replace"][0];
  EXPECT_EQ(replace["effect"], "range_noise_linear");
  EXPECT_EQ(replace["replacement"]["effect"], "range_noise_piecewise");
  EXPECT_GT(replace["delta_bic_vs_additive"].get<double>(), 10.0);
  // The plateau from 1.02 to 19.6 m (knots 2 and 3, tied) holds the hall's walls and floor.
  const auto& plateau = replace["replacement"]["params"]["points_m/2/1"];
  std::printf("  1-20 m plateau: %.5f [%.5f, %.5f] (truth 0.01)\n", plateau["value"].get<double>(),
              plateau["ci95"][0].get<double>(), plateau["ci95"][1].get<double>());
  EXPECT_NEAR(plateau["value"].get<double>(), 0.01, 0.0005) << plateau.dump();
  // The effects the paper's profile lacks, added given the table: incidence at os1-64's divergence,
  // and its signal-driven dropout (threshold 4 photons, width 0.3: the effect's defaults), nothing else.
  std::set<std::string> selected;
  for (const auto& c : d["selected"]) {
    selected.insert(c["effect"].get<std::string>());
    if (c["effect"] == "incidence") expect_covers(c["params"], "divergence_rad", divergence);
    if (c["effect"] == "dropout") {
      expect_covers(c["params"], "threshold_photons", 4.0);
      expect_covers(c["params"], "width", 0.3);
    }
  }
  EXPECT_EQ(selected, (std::set<std::string>{"dropout", "incidence"})) << d["selected"].dump(1);
  expect_robust_intervals(d["selected"]);
  EXPECT_EQ(d["remaining"]["failing_regions"], 0) << d["remaining"].dump();
  EXPECT_EQ(d["intervals_caveat"], "") << "the model fits once the law is replaced";

  // With the paper's law kept (--keep-profile), incidence is fitted beside a wrong law: its
  // divergence is pulled off the truth, as issue 24 met it (0.00192 [0.00191, 0.00193] against
  // 0.00227). The diagnosis says so beside the intervals: the terminal, report.json, report.html.
  // The robust interval sees the wrong spread and widens (about 3 times here), but no interval
  // conditional on the model reaches a truth the wrong law pulls the value from: the caveat says so.
  const fs::path kept = dir / "kept";
  const test::CliRun k = run_cli("compare" + inputs +
                                 " --frames 2 --diagnose --keep-profile --profile os1-32-paper --out " + kept.string());
  ASSERT_EQ(k.exit_code, 0) << k.output;
  const nlohmann::json dk = read_json(kept / "report.json")["diagnosis"];
  ASSERT_FALSE(dk["selected"].empty()) << dk.dump(1);
  EXPECT_GT(dk["remaining"]["failing_regions"].get<int>(), 0) << dk["remaining"].dump();
  const std::string caveat = dk["intervals_caveat"];
  EXPECT_EQ(caveat.rfind("The intervals hold if the rest of the model is right, and it is not", 0), 0u) << caveat;
  EXPECT_NE(k.output.find(caveat), std::string::npos) << k.output;
  for (const auto& c : dk["selected"]) {
    if (c["effect"] != "incidence") continue;
    const auto& p = c["params"]["divergence_rad"];
    std::printf("  beside the wrong law: divergence %.6g [%.6g, %.6g], robust [%.6g, %.6g], truth %.6g\n",
                p["value"].get<double>(), p["ci95"][0].get<double>(), p["ci95"][1].get<double>(),
                p["ci95_robust"][0].get<double>(), p["ci95_robust"][1].get<double>(), divergence);
    const double width = p["ci95"][1].get<double>() - p["ci95"][0].get<double>();
    EXPECT_GT(p["ci95_robust"][1].get<double>() - p["ci95_robust"][0].get<double>(), 1.5 * width) << p.dump();
  }
  std::ifstream page(kept / "report.html");
  const std::string html((std::istreambuf_iterator<char>(page)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("<b>About the intervals:</b> The intervals hold if the rest of the model is right"),
            std::string::npos);
  EXPECT_NE(html.find("(robust ["), std::string::npos);

  const fs::path fitted = dir / "fitted.json";
  const test::CliRun fit =
      run_cli("fit" + inputs +
              " --frames 2 --profile os1-32-paper --replace range_noise_linear=range_noise_piecewise"
              " --add dropout --add incidence --out " +
              fitted.string());
  ASSERT_EQ(fit.exit_code, 0) << fit.output;
  std::printf("%s", fit.output.c_str());
  const nlohmann::json profile = read_json(fitted);
  bool table = false, incidence = false;
  for (const auto& effect : profile["effects"]) {
    EXPECT_NE(effect["name"], "range_noise_linear") << effect;
    table = table || effect["name"] == "range_noise_piecewise";
    incidence = incidence || effect["name"] == "incidence";
  }
  EXPECT_TRUE(table && incidence) << profile["effects"].dump(1);
  expect_held_out_fit(inputs, "os1-32-paper", fitted, 2, dir / "held_out");
  fs::remove_all(dir);
}

// E2 beside incidence (the generator's k 0.3 m sqrt(photon), a 3 mm floor, a 3 mrad beam) against
// the datasheet table without either: incidence is added first (the oblique walls' spread is the
// larger misfit), then the table is replaced. In this room the signal falls as 1 / r^2 on walls of
// one reflectivity, so k / sqrt(S) grows nearly as r does and a linear sigma(r) comes close to E2;
// what tells them apart is the oblique returns, which incidence fitted beside the table had partly
// absorbed. Given that incidence the linear law scored above E2 (by 500 BIC); with incidence
// refitted beside each law (diagnosis' refit_with_kept) E2 wins, at the generator's values.
TEST(CompareNoiseLaw, ASpreadThatFollowsTheSignalBesideIncidenceReplacesTheTableBySignalPrecision) {
  const fs::path dir = fresh_dir("e2_incidence");
  const std::string inputs =
      generated_room(dir, "--frames 5 --seed 4 --sigma0 0.003 --slope 0 --snr-k 0.3 --divergence 0.003");
  const nlohmann::json truth = read_json(dir / "truth.json");
  const test::CliRun r =
      run_cli("compare" + inputs + " --no-plots --diagnose --profile " +
              table_profiles::table_profile("os1-64").string() + " --out " + (dir / "report").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json d = read_json(dir / "report" / "report.json")["diagnosis"];
  ASSERT_EQ(d["replace"].size(), 1u) << d.dump(1);
  const auto& replace = d["replace"][0];
  EXPECT_EQ(replace["effect"], "range_noise_piecewise");
  EXPECT_EQ(replace["replacement"]["effect"], "signal_precision") << replace.dump(1);
  expect_covers(replace["replacement"]["params"], "k_m", truth["snr_k_m"].get<double>());
  expect_covers(replace["replacement"]["params"], "floor_m", truth["range_noise"]["sigma0_m"].get<double>());
  ASSERT_EQ(d["selected"].size(), 1u) << d["selected"].dump(1);
  EXPECT_EQ(d["selected"][0]["effect"], "incidence");
  expect_covers(d["selected"][0]["params"], "divergence_rad", truth["divergence_rad"].get<double>());
  EXPECT_NE(r.output.find("--replace range_noise_piecewise=signal_precision --add incidence"), std::string::npos)
      << r.output;
  EXPECT_EQ(d["remaining"]["failing_regions"], 0) << d["remaining"].dump();
  fs::remove_all(dir);
}

// The reverse: the generator's own linear law (10 mm + 1.4 mm/m) against the datasheet table
// (os1-64 with its table effects only): the table is replaced by the linear law, whose sigma at 0
// and at the table's last knot (100 m) cover the generator's 10 and 150 mm.
TEST(CompareNoiseLaw, ALinearSpreadAgainstTheDatasheetTableReplacesTheTableByTheLinearLaw) {
  const fs::path dir = fresh_dir("linear");
  const std::string inputs = generated_room(dir, "--frames 3 --seed 1");
  const nlohmann::json truth = read_json(dir / "truth.json")["range_noise"];
  const test::CliRun r =
      run_cli("compare" + inputs + " --no-plots --diagnose --profile " +
              table_profiles::table_profile("os1-64").string() + " --out " + (dir / "report").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json d = read_json(dir / "report" / "report.json")["diagnosis"];
  ASSERT_EQ(d["replace"].size(), 1u) << d.dump(1);
  const auto& replace = d["replace"][0];
  EXPECT_EQ(replace["effect"], "range_noise_piecewise");
  EXPECT_EQ(replace["replacement"]["effect"], "range_noise_linear");
  EXPECT_GT(replace["delta_bic_vs_additive"].get<double>(), 10.0);
  const double sigma0 = truth["sigma0_m"].get<double>();
  expect_covers(replace["replacement"]["params"], "sigma0_m", sigma0);
  // sigma_max_m is the law at 100 m, extrapolated from a room whose ranges end at 13 m: its interval
  // holds the fit's noise, not the extrapolation's (seed 1: 0.1469, 95 % 0.1440-0.1498, truth 0.15).
  const auto& sigma_max = replace["replacement"]["params"]["sigma_max_m"];
  EXPECT_NEAR(sigma_max["value"].get<double>(), sigma0 + 100.0 * truth["slope"].get<double>(), 0.005)
      << sigma_max.dump();
  EXPECT_TRUE(d["selected"].empty()) << d["selected"].dump(1);
  EXPECT_TRUE(d["unexplained"].empty()) << d["unexplained"].dump(1);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lidartwin::cli_compare_noise_law_test
