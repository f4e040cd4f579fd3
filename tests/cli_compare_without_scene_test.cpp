// `lidartwin compare` without a scene, as a user with a real sensor runs it: --static from two
// frames of a motionless sensor, and --map for a moving one, whose frames are placed by a given
// trajectory or registered to each other. Judged against what the scene-based comparison of the
// same capture says, and against a profile that is wrong.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"
#include "support/table_profile.h"

namespace cli_compare_without_scene_test {

namespace fs = std::filesystem;

namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;

std::string os1_64() {
  static const std::string path = table_profiles::table_profile("os1-64").string();
  return path;
}

using lidartwin::test::CliRun;
using lidartwin::test::run_cli;

nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

fs::path temp(const std::string& name) {
  const fs::path dir = fs::path(testing::TempDir()) / (name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  return dir;
}

// The single-feature bins of `feature` with at least `min_inliers` inliers.
std::vector<nlohmann::json> bins_of(const nlohmann::json& report, const std::string& feature, size_t min_inliers) {
  std::vector<nlohmann::json> out;
  for (const auto& bin : report["bins"]) {
    if (bin["features"].size() == 1 && bin["features"].contains(feature) &&
        bin["inliers"].get<size_t>() >= min_inliers) {
      out.push_back(bin);
    }
  }
  return out;
}

TEST(CompareStatic, TwoFramesOfAMotionlessSensorJudgeItsSpread) {
  const fs::path capture = temp("static_two_frames");
  ASSERT_EQ(run_cli("record --profile " + os1_64() + " --scene " + kSource + "/scenes/calibration_hall.glb" +
                    " --trajectory " + kSource + "/scenes/calibration_hall_static.tum --frames 2 --seed 3 --out " +
                    capture.string())
                .exit_code,
            0);
  const fs::path same = temp("static_two_frames_same");
  const CliRun r = run_cli("compare --static --capture " + capture.string() + " --profile " + os1_64() + " --out " +
                           same.string() + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = read_json(same / "report.json");
  EXPECT_TRUE(report["failing"].empty()) << report["failing"][0]["sentence"];
  const auto ranges = bins_of(report, "range", 2000);
  ASSERT_GE(ranges.size(), 2u);
  for (const auto& bin : ranges) EXPECT_NEAR(bin["spread_ratio"].get<double>(), 1.0, 0.05) << bin.dump();

  // The paper's linear law is 1.5-2 times the datasheet's sigma over the hall's ranges.
  const fs::path paper = temp("static_two_frames_paper");
  ASSERT_EQ(run_cli("compare --static --capture " + capture.string() + " --profile os1-32-paper --out " +
                    paper.string() + " --no-plots")
                .exit_code,
            0);
  const nlohmann::json wrong = read_json(paper / "report.json");
  ASSERT_FALSE(wrong["failing"].empty());
  EXPECT_EQ(wrong["failing"][0]["quantity"], "spread");
  fs::remove_all(capture);
  fs::remove_all(same);
  fs::remove_all(paper);
}

TEST(CompareStatic, OneFrameIsRefusedAndSaysWhatItNeeds) {
  const std::string dir = kSource + "/tests/data/ouster-samples/";
  const fs::path out = temp("static_one_frame");
  const CliRun r =
      run_cli("compare --static --frames 1 --capture " + dir + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap" + " --metadata " +
              dir + "OS-1-128_v2.3.0_1024x10.json --profile os1-128 --out " + out.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("needs at least 2"), std::string::npos) << r.output;
}

// A drive through the plant, 2.5 m/s and 10 deg/s, 1.7 m above the ground.
class CompareMap : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    drive_ = temp("map_drive");
    fs::create_directories(drive_);
    std::ofstream(drive_ / "drive.tum") << "0 10 9 1.7 0 0 0 1\n3 17.5 9 1.7 0 0 0.0871557 0.9961947\n";
    const CliRun r = run_cli("record --profile " + os1_64() + " --scene " + kSource + "/scenes/plant.glb" +
                             " --trajectory " + (drive_ / "drive.tum").string() +
                             " --uptime-s 0 --frames 12 --seed 5 --out " + (drive_ / "capture").string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() { fs::remove_all(drive_); }
  static std::string capture_args() {
    return " --capture " + (drive_ / "capture" / "capture.pcap").string() + " --metadata " +
           (drive_ / "capture" / "metadata.json").string();
  }
  static inline fs::path drive_;
};

TEST_F(CompareMap, WithTheTrajectoryTheSpreadIsJudgedAsWithTheScene) {
  const fs::path out = drive_ / "map_truth";
  const CliRun r = run_cli("compare --map" + capture_args() + " --pose " + (drive_ / "capture" / "poses.tum").string() +
                           " --profile " + os1_64() + " --out " + out.string() + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("returns compared"), std::string::npos) << r.output;
  const nlohmann::json report = read_json(out / "report.json");
  const auto& map = report["inputs"]["map"];
  EXPECT_GT(map["compared"].get<size_t>(), 50000u);
  EXPECT_EQ(map["compared"].get<size_t>(), report["summary"]["pixels"].get<size_t>());
  // Overall the residuals about the other frames' surfaces spread as the profile says, within
  // what the reference's unmodelled error still adds (map mode's known limit: up to 1.1 times in
  // the 13-20 m band here, docs/compare-report.md); the paper's law below is off by 1.5-2 times.
  EXPECT_NEAR(report["summary"]["z"]["std"].get<double>(), 1.0, 0.05);
  size_t checked = 0;
  for (const auto& bin : bins_of(report, "range", 5000)) {
    EXPECT_NEAR(bin["spread_ratio"].get<double>(), 1.0, 0.12) << bin.dump();
    ++checked;
  }
  EXPECT_GE(checked, 2u);
  for (const auto& bin : report["bins"]) EXPECT_FALSE(bin["features"].contains("material"));

  // Against the paper's law (sigma 1.5-2 times the datasheet's) the spread fails, first.
  const fs::path paper = drive_ / "map_paper";
  ASSERT_EQ(run_cli("compare --map" + capture_args() + " --pose " + (drive_ / "capture" / "poses.tum").string() +
                    " --profile os1-32-paper --out " + paper.string() + " --no-plots")
                .exit_code,
            0);
  const nlohmann::json wrong = read_json(paper / "report.json");
  ASSERT_FALSE(wrong["failing"].empty());
  size_t spread_low = 0;
  for (const auto& bin : bins_of(wrong, "range", 5000)) spread_low += bin["spread_ratio"].get<double>() < 0.8;
  EXPECT_GE(spread_low, 2u);
}

TEST_F(CompareMap, WithoutATrajectoryTheFramesAreRegisteredToEachOther) {
  const fs::path out = drive_ / "map_registered";
  const CliRun r =
      run_cli("compare --map" + capture_args() + " --profile " + os1_64() + " --out " + out.string() + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("frames registered to each other"), std::string::npos) << r.output;
  const nlohmann::json report = read_json(out / "report.json");
  // 12 frames at 2.5 m/s: 3 m.
  EXPECT_NEAR(report["inputs"]["registration"]["path_length_m"].get<double>(), 3.0, 0.3);
  std::ifstream tum(out / "registered_poses.tum");
  std::string line, last;
  size_t rows = 0;
  while (std::getline(tum, line)) {
    if (!line.empty() && line[0] != '#') {
      last = line;
      ++rows;
    }
  }
  EXPECT_EQ(rows, 13u);  // a knot at each frame's start and where the last one ends
  double t = 0, x = 0, y = 0, z = 0;
  ASSERT_EQ(std::sscanf(last.c_str(), "%lf %lf %lf %lf", &t, &x, &y, &z), 4);
  // The truth, in the first frame's sensor frame: 3 m straight ahead (yawing as it goes) on level ground.
  EXPECT_NEAR(x, 3.0, 0.2);
  EXPECT_NEAR(y, 0.0, 0.2);
  EXPECT_NEAR(z, 0.0, 0.05);
  EXPECT_GT(report["inputs"]["map"]["compared"].get<size_t>(), 30000u);
}

// A capture of one frame has no other frame to make a reference of (the OS-1-32-G sample): map mode
// says so and makes each return's reference from the frame's own returns around it (--within-frame);
// --skip-frames cannot leave out every frame; --frames 1 scores one frame against the others.
TEST_F(CompareMap, OneFrameIsComparedWithinTheFrame) {
  const std::string samples = kSource + "/tests/data/ouster-samples/";
  const CliRun one =
      run_cli("compare --map --no-plots --capture " + samples + "OS-1-32-G_v2.1.1_1024x10.pcap --metadata " + samples +
              "OS-1-32-G_v2.1.1_1024x10.json --profile os1-32 --out " + (drive_ / "map_one").string());
  ASSERT_EQ(one.exit_code, 0) << one.output;
  EXPECT_NE(one.output.find("holds one frame"), std::string::npos) << one.output;
  EXPECT_NE(one.output.find("map (within each frame)"), std::string::npos) << one.output;
  const nlohmann::json report = read_json(drive_ / "map_one" / "report.json");
  EXPECT_TRUE(report["inputs"]["map"]["within_frame"].get<bool>());
  EXPECT_GT(report["inputs"]["map"]["compared"].get<size_t>(), 1000u);
  const CliRun needs_map = run_cli("compare --within-frame" + capture_args() + " --profile " + os1_64() + " --out " +
                                   (drive_ / "within_alone").string());
  EXPECT_NE(needs_map.exit_code, 0);
  EXPECT_NE(needs_map.output.find("--map"), std::string::npos) << needs_map.output;
  const CliRun none = run_cli("compare --map --skip-frames 1000" + capture_args() + " --profile " + os1_64() +
                              " --out " + (drive_ / "map_none").string());
  EXPECT_NE(none.exit_code, 0);
  EXPECT_NE(none.output.find("--skip-frames 1000"), std::string::npos) << none.output;
  const CliRun first = run_cli("compare --map --frames 1 --no-plots" + capture_args() + " --profile " + os1_64() +
                               " --out " + (drive_ / "map_first").string());
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_EQ(read_json(drive_ / "map_first" / "report.json")["inputs"]["frames"].get<size_t>(), 1u);
}

// A drive recorded with the shipped os1-64 (less E6's mixed pixels, which map mode leaves out at
// edges and cannot predict), compared with that same profile: its incidence effect (E4) makes the
// ground's spread at 80-85 degrees change by a tenth per degree, so map mode's spread there is only
// as right as the incidence it estimates. On the returns both modes judged
// (tests/tools/same_returns_spread.py), per range bin of 5,000 or more, map mode's spread ratio is
// the scene's within 5 % and its incidence the scene's within 0.15 degrees, median. (Taken from the
// reference's own patch, the ground's incidence at 8-13 m read 0.26 degrees low, median, with a tail
// to -5, and the spread 1.07 times the scene's; from a strip along the beam: 0.01, 1.01.)
TEST(CompareMapShippedProfile, TheGroundAtGrazingIncidenceIsJudgedAsWithTheScene) {
  const fs::path dir = temp("map_shipped");
  fs::create_directories(dir);
  std::ifstream in(kSource + "/profiles/os1-64.json");
  nlohmann::json profile = nlohmann::json::parse(in);
  auto& effects = profile["effects"];
  effects.erase(
      std::remove_if(effects.begin(), effects.end(), [](const auto& e) { return e["name"] == "mixed_pixels"; }),
      effects.end());
  std::ofstream(dir / "shipped.json") << profile.dump(2);
  std::ofstream(dir / "drive.tum") << "0 12 9 1.7 0 0 0 1\n3 19.5 9 1.7 0 0 0.0871557 0.9961947\n";
  ASSERT_EQ(run_cli("record --profile " + (dir / "shipped.json").string() + " --scene " + kSource +
                    "/scenes/plant.glb --trajectory " + (dir / "drive.tum").string() +
                    " --uptime-s 0 --frames 6 --seed 5 --out " + (dir / "capture").string())
                .exit_code,
            0);
  const std::string inputs = " --no-plots --pixels --capture " + (dir / "capture" / "capture.pcap").string() +
                             " --metadata " + (dir / "capture" / "metadata.json").string() + " --pose " +
                             (dir / "capture" / "poses.tum").string() + " --profile " + (dir / "shipped.json").string();
  const CliRun scene =
      run_cli("compare" + inputs + " --scene " + kSource + "/scenes/plant.glb --out " + (dir / "scene").string());
  ASSERT_EQ(scene.exit_code, 0) << scene.output;
  const CliRun map = run_cli("compare --map" + inputs + " --out " + (dir / "map").string());
  ASSERT_EQ(map.exit_code, 0) << map.output;
  const std::string script = "/usr/bin/python3 " + kSource + "/tests/tools/same_returns_spread.py " +
                             (dir / "scene").string() + " " + (dir / "map").string() + " > " +
                             (dir / "same.json").string();
  ASSERT_EQ(std::system(script.c_str()), 0) << script;
  const nlohmann::json same = read_json(dir / "same.json");
  size_t compared = 0;
  for (const auto& bin : same["range"]) {
    if (bin["inliers"].get<size_t>() < 5000) continue;
    EXPECT_NEAR(bin["map"].get<double>() / bin["scene"].get<double>(), 1.0, 0.05) << bin.dump();
    EXPECT_NEAR(bin["incidence_deg_map_less_scene"].get<double>(), 0.0, 0.15) << bin.dump();
    ++compared;
  }
  EXPECT_GE(compared, 2u) << same.dump();  // 5-8 m and 8-13 m, mostly the ground at 75-85 degrees
  fs::remove_all(dir);
}

}  // namespace

namespace {

// Real captures, which lidartwin did not write (tests/data/ouster-samples, BSD-3-Clause).
const std::string kSamples = kSource + "/tests/data/ouster-samples/";

double ratio_in(const nlohmann::json& report, const std::string& feature, double lo) {
  for (const auto& bin : bins_of(report, feature, 0)) {
    if (bin["features"][feature][0].get<double>() == lo) return bin["spread_ratio"].get<double>();
  }
  ADD_FAILURE() << "no " << feature << " bin from " << lo;
  return 0.0;
}
double measured_spread_in(const nlohmann::json& report, const std::string& feature, double lo) {
  for (const auto& bin : bins_of(report, feature, 0)) {
    if (bin["features"][feature][0].get<double>() == lo) return bin["spread_m"]["measured"].get<double>();
  }
  ADD_FAILURE() << "no " << feature << " bin from " << lo;
  return 0.0;
}

// The datasheet's profile, before these captures refitted the shipped one (E2 and all).
std::string datasheet_os1_128() {
  static const std::string path = table_profiles::datasheet_only_profile("os1-128").string();
  return path;
}

// The OS-1-128 sample was taken from a vehicle (2.5 m/s, found by registering its frames by hand):
// map mode registers it, finds the datasheet table's spread too small beyond 13 m and a spread that
// falls with reflectivity, which a sigma(range) cannot hold, and the diagnosis names E2. The shipped
// os1-128, refitted on this capture, explains it better (in sample: it was fitted on these frames;
// MapModeFitOnTwoFramesLowersTheErrorOnTheThird judges a fit out of sample).
TEST(CompareRealCapture, MapModeOnAMovingOs1128NamesSignalDependentPrecision) {
  const fs::path out = temp("real_os1_128_map");
  const CliRun r = run_cli("compare --map --diagnose --capture " + kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap" +
                           " --metadata " + kSamples + "OS-1-128_v2.3.0_1024x10.json --profile os1-128 --profile " +
                           datasheet_os1_128() + " --out " + out.string() + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = read_json(out / "report.json");
  EXPECT_NEAR(report["inputs"]["registration"]["path_length_m"].get<double>(), 0.75, 0.15);  // 0.3 s at 2.5 m/s
  EXPECT_GT(report["inputs"]["map"]["compared"].get<size_t>(), 100000u);
  EXPECT_GT(ratio_in(report, "range", 13.0), 1.08);
  EXPECT_GT(ratio_in(report, "range", 20.0), 1.05);
  EXPECT_GT(ratio_in(report, "reflectivity", 0.0), ratio_in(report, "reflectivity", 40.0) + 0.2);
  // E2 is named added to the table, or in its place: refitted with a saturating footprint, the
  // datasheet's incidence takes much of the oblique returns' excess, and E2 alone then explains the
  // rest better than the table does.
  bool e2 = false;
  const nlohmann::json& replace = report["diagnosis"]["replace"];
  for (const auto& law : replace.is_array() ? replace : nlohmann::json::array({replace})) {
    e2 |= law.is_object() && law["replacement"]["effect"] == "signal_precision";
  }
  std::optional<double> beam_104;  // reads 33 mm long against the other beams' surfaces
  for (const auto& c : report["diagnosis"]["selected"]) {
    e2 |= c["effect"] == "signal_precision";
    if (c["effect"] == "beam_calibration" && c["params"].contains("offsets_m/104")) {
      beam_104 = c["params"]["offsets_m/104"]["value"].get<double>();
    }
  }
  EXPECT_TRUE(e2) << report["diagnosis"].dump();
  ASSERT_TRUE(beam_104.has_value()) << report["diagnosis"]["selected"].dump();
  EXPECT_NEAR(*beam_104, 0.033, 0.008);
  const nlohmann::json& shipped = report["waterfall"][0];
  const nlohmann::json& datasheet = report["waterfall"][1];
  EXPECT_LT(shipped["nll_per_pixel"].get<double>(),
            datasheet["nll_per_pixel"].get<double>() - 10.0 * datasheet["nll_se"].get<double>());
  fs::remove_all(out);
}

// A waterfall row's NLL excess in standard errors of what its own model expects.
double excess_se(const nlohmann::json& row) {
  return (row["nll_per_pixel"].get<double>() - row["nll_expected"].get<double>()) / row["nll_se"].get<double>();
}

// The loop on real data, judged on a frame the fit never scored: fit --auto on the sample's first
// two frames, from the datasheet's profile, then compare that and the fitted one on the third. In
// map mode every frame still makes reference surfaces, so the held-out frame is judged against the
// same map.
TEST(CompareRealCapture, MapModeFitOnTwoFramesLowersTheErrorOnTheThird) {
  const fs::path out = temp("real_os1_128_held_out");
  const std::string in = " --map --capture " + kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap --metadata " + kSamples +
                         "OS-1-128_v2.3.0_1024x10.json";
  const fs::path fitted = out / "fitted.json";
  const CliRun fit =
      run_cli("fit" + in + " --frames 2 --auto --profile " + datasheet_os1_128() + " --out " + fitted.string());
  ASSERT_EQ(fit.exit_code, 0) << fit.output;
  const nlohmann::json profile = read_json(fitted);
  EXPECT_EQ(profile["fit"]["frames"].get<size_t>(), 2u);
  bool e2 = false;
  for (const auto& effect : profile["effects"]) e2 |= effect["name"] == "signal_precision";
  EXPECT_TRUE(e2) << profile["effects"].dump();

  const CliRun judged = run_cli("compare" + in + " --skip-frames 2 --profile " + datasheet_os1_128() + " --profile " +
                                fitted.string() + " --out " + (out / "held_out").string() + " --no-plots");
  ASSERT_EQ(judged.exit_code, 0) << judged.output;
  const nlohmann::json report = read_json(out / "held_out" / "report.json");
  EXPECT_EQ(report["inputs"]["frames"].get<size_t>(), 1u);
  EXPECT_EQ(report["inputs"]["skipped_frames"].get<size_t>(), 2u);
  EXPECT_GT(report["inputs"]["map"]["compared"].get<size_t>(), 30000u);
  const nlohmann::json& shipped = report["waterfall"][0];
  const nlohmann::json& refit = report["waterfall"][1];
  // The fitted profile explains the held-out frame better, and nearer to what its own model
  // expects. Not within a few standard errors of it: the frame still fails where neither profile
  // has an effect (incidence 30-60 degrees, 1.3 times the spread), and a fit on two frames of a
  // sensor's own map leaves the spread a little wide elsewhere (-7 standard errors, spread 0.99).
  EXPECT_LT(refit["nll_per_pixel"].get<double>(),
            shipped["nll_per_pixel"].get<double>() - 5.0 * shipped["nll_se"].get<double>());
  EXPECT_GT(std::abs(excess_se(shipped)), 5.0);
  EXPECT_LT(std::abs(excess_se(refit)), std::abs(excess_se(shipped))) << refit.dump();
  // The per-beam offsets fitted on two frames hold on the third (beam 104 reads 33 mm long).
  bool beams = false;
  for (const auto& effect : profile["effects"]) beams |= effect["name"] == "beam_calibration";
  EXPECT_TRUE(beams) << profile["effects"].dump();
  EXPECT_LT(refit["bias_rms_m"].get<double>(), 0.8 * shipped["bias_rms_m"].get<double>()) << refit.dump();
  fs::remove_all(out);
}

// What the shipped OS1 profiles carry of that capture is the product's part of the fit, not the
// unit's (its beam offsets): incidence with a saturating footprint, E2 and E2's tails, fitted
// together. Fitted so on two frames, each part holds on the third (measured, NLL per pixel of the
// held-out frame: 2.544 without the tails, 2.520 with them and the footprint law, 2.514 with them and
// the saturating footprint, whose divergence then fits the datasheet's 0.18 degrees: 0.0035 rad
// against 0.0019 with the footprint law); the shipped os1-128, the same fit on all three frames, does
// as well there.
TEST(CompareRealCapture, TheOs1LinesTailsAndSaturatingFootprintHoldOnAHeldOutFrame) {
  const fs::path out = temp("real_os1_128_tails");
  fs::create_directories(out);
  const std::string in = " --map --capture " + kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap --metadata " + kSamples +
                         "OS-1-128_v2.3.0_1024x10.json";
  nlohmann::json bare = read_json(kSource + "/profiles/os1-128.json");
  nlohmann::json kept = nlohmann::json::array();
  for (const auto& effect : bare["effects"]) {
    const auto& name = effect["name"];
    if (name != "incidence" && name != "signal_precision" && name != "signal_outliers") kept.push_back(effect);
  }
  ASSERT_EQ(kept.size() + 3, bare["effects"].size()) << "os1-128 lacks incidence, E2 or its tails";
  bare["effects"] = kept;
  std::ofstream(out / "bare.json") << bare.dump(2);
  const auto fit = [&](const std::string& add, const std::string& name) {
    const fs::path path = out / (name + ".json");
    const CliRun r =
        run_cli("fit" + in + " --frames 2 --profile " + (out / "bare.json").string() + add + " --out " + path.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return path.string();
  };
  const std::string saturating = R"( --add '{"name": "incidence", "divergence_rad": 0.002, "saturation": 0.3}')";
  const std::string no_tails = fit(saturating + " --add signal_precision", "no_tails");
  const std::string tails = fit(saturating + " --add signal_precision --add signal_outliers", "tails");
  const std::string footprint_law = fit(" --add incidence --add signal_precision --add signal_outliers", "law");
  const CliRun judged =
      run_cli("compare" + in + " --skip-frames 2 --profile " + no_tails + " --profile " + tails + " --profile " +
              footprint_law + " --profile os1-128 --out " + (out / "held_out").string() + " --no-plots");
  ASSERT_EQ(judged.exit_code, 0) << judged.output;
  const nlohmann::json report = read_json(out / "held_out" / "report.json");
  const nlohmann::json& without_tails = report["waterfall"][0];
  const nlohmann::json& with_tails = report["waterfall"][1];
  const nlohmann::json& law = report["waterfall"][2];
  const nlohmann::json& shipped = report["waterfall"][3];
  const auto nll = [](const nlohmann::json& row) { return row["nll_per_pixel"].get<double>(); };
  const std::string rows = report["waterfall"].dump();
  EXPECT_LT(nll(with_tails), nll(without_tails) - 3.0 * without_tails["nll_se"].get<double>()) << rows;
  EXPECT_LT(std::abs(excess_se(with_tails)), std::abs(excess_se(without_tails))) << rows;
  EXPECT_LT(nll(with_tails), nll(law)) << rows;
  EXPECT_LT(with_tails["failing_regions"].get<int>(), law["failing_regions"].get<int>()) << rows;
  EXPECT_NEAR(nll(shipped), nll(with_tails), with_tails["nll_se"].get<double>()) << rows;
  // With the footprint saturating, the footprint's width is the datasheet's (0.18 degrees FWHM).
  const nlohmann::json fitted = read_json(tails);
  for (const auto& effect : fitted["effects"]) {
    if (effect["name"] != "incidence") continue;
    EXPECT_NEAR(effect["divergence_rad"].get<double>(), 0.00314, 0.0006) << effect.dump();
    EXPECT_GT(effect["saturation"].get<double>(), 0.12) << effect.dump();  // tan(theta) saturating at 8 or less
    EXPECT_LT(effect["saturation"].get<double>(), 0.4) << effect.dump();
  }
  fs::remove_all(out);
}

// The OS2 profiles as shipped before the OS-2-128 sample refitted them: the placeholder table, the
// default radiometry, no incidence effect and no tails.
std::string os2_before_the_fit(const std::string& shipped) {
  const fs::path dir = temp("os2_before");
  fs::create_directories(dir);
  std::ifstream in(kSource + "/profiles/" + shipped + ".json");
  nlohmann::json profile = nlohmann::json::parse(in);
  table_profiles::keep_table_effects(profile["effects"]);
  for (auto& effect : profile["effects"]) {
    if (effect["name"] == "radiometry") effect = {{"name", "radiometry"}};
  }
  const fs::path path = dir / (shipped + "-before.json");
  std::ofstream(path) << profile.dump(2);
  return path.string();
}

// The OS-2-128 sample is one frame: map mode compares it within the frame. Against the placeholder
// table its spread is about twice the model's and grows with incidence (13 mm below 30 degrees, 58
// at 60-75); the diagnosis keeps incidence. The shipped os2 profiles were fitted there (incidence,
// E2's tails, the signal channel); judged on the other OS2 sample, another unit the fit never saw
// (OS-2-32-U0), they still explain it far better than the table (excess +215 -> +30 standard errors).
TEST(CompareRealCapture, WithinAFrameTheOs2SpreadGrowsWithIncidenceAndTheFitHoldsOnAnotherUnit) {
  const fs::path out = temp("real_os2_128");
  const CliRun r = run_cli("compare --map --diagnose --no-plots --capture " + kSamples +
                           "OS-2-128-U1_v2.3.0_1024x10.pcap --metadata " + kSamples +
                           "OS-2-128-U1_v2.3.0_1024x10.json --profile os2-128 --profile " +
                           os2_before_the_fit("os2-128") + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = read_json(out / "report.json");
  EXPECT_TRUE(report["inputs"]["map"]["within_frame"].get<bool>());
  EXPECT_GT(report["inputs"]["map"]["compared"].get<size_t>(), 20000u);
  EXPECT_GT(ratio_in(report, "incidence", 45.0), 1.5);
  EXPECT_GT(measured_spread_in(report, "incidence", 60.0), 2.5 * measured_spread_in(report, "incidence", 0.0));
  bool incidence = false;
  for (const auto& c : report["diagnosis"]["selected"]) incidence |= c["effect"] == "incidence";
  EXPECT_TRUE(incidence) << report["diagnosis"]["selected"].dump();
  const nlohmann::json& shipped = report["waterfall"][0];
  const nlohmann::json& before = report["waterfall"][1];
  EXPECT_GT(excess_se(before), 100.0);
  EXPECT_LT(std::abs(excess_se(shipped)), 20.0);

  const fs::path other = temp("real_os2_32");
  const CliRun o =
      run_cli("compare --map --no-plots --capture " + kSamples + "OS-2-32-U0_v2.0.0_1024x10.pcap --metadata " +
              kSamples + "OS-2-32-U0_v2.0.0_1024x10.json --profile os2-32 --profile " + os2_before_the_fit("os2-32") +
              " --out " + other.string());
  ASSERT_EQ(o.exit_code, 0) << o.output;
  const nlohmann::json unit = read_json(other / "report.json");
  EXPECT_LT(excess_se(unit["waterfall"][0]), excess_se(unit["waterfall"][1]) / 3.0);
  EXPECT_LT(unit["waterfall"][0]["nll_per_pixel"].get<double>(),
            unit["waterfall"][1]["nll_per_pixel"].get<double>() - 50.0 * unit["waterfall"][1]["nll_se"].get<double>());
}

// crc_test.pcap: a motionless OS-0-128 whose two frames share 32 columns. Static mode from those
// two frames sees what was measured by hand: about 13 mm of spread on dark targets, a quarter of
// that on bright ones, where the shipped profile predicts one sigma for both.
TEST(CompareRealCapture, StaticModeOnAMotionlessOs0128SeesSpreadFallWithReflectivity) {
  const fs::path out = temp("real_os0_128_static");
  const CliRun r = run_cli("compare --static --capture " + kSamples + "crc_test.pcap --metadata " + kSamples +
                           "crc_test.json --profile os0-128 --out " + out.string() + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = read_json(out / "report.json");
  const double dark = measured_spread_in(report, "reflectivity", 0.0);
  const double bright = measured_spread_in(report, "reflectivity", 40.0);
  EXPECT_NEAR(dark, 0.013, 0.003);
  EXPECT_LT(bright, 0.3 * dark);
  ASSERT_FALSE(report["failing"].empty());
  fs::remove_all(out);
}

// The same two frames with --diagnose, against os0-128 as it was before this capture gave it E2's
// tails: dark targets' returns differ between the frames by 3-20 cm a fifth of the time (5.9 %
// beyond 5 sigma at the lowest near-IR), which no Gaussian law holds. The diagnosis names the tails
// (signal_outliers), and the failing regions fall by more than half.
TEST(CompareRealCapture, StaticDiagnosisOfAMotionlessOs0128NamesTheTailsOfWeakReturns) {
  const fs::path out = temp("real_os0_128_static_tails");
  fs::create_directories(out);
  nlohmann::json before = read_json(kSource + "/profiles/os0-128.json");
  auto& effects = before["effects"];
  const auto shipped_tails =
      std::find_if(effects.begin(), effects.end(), [](const auto& e) { return e["name"] == "signal_outliers"; });
  ASSERT_NE(shipped_tails, effects.end()) << "the shipped os0-128 carries the tails this capture gave it";
  effects.erase(shipped_tails);
  std::ofstream(out / "os0-128-before.json") << before.dump();
  const CliRun r = run_cli("compare --static --diagnose --capture " + kSamples + "crc_test.pcap --metadata " +
                           kSamples + "crc_test.json --profile " + (out / "os0-128-before.json").string() + " --out " +
                           out.string() + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = read_json(out / "report.json");
  const nlohmann::json& d = report["diagnosis"];
  const nlohmann::json* tails = nullptr;
  for (const auto& c : d["selected"]) {
    if (c["effect"] == "signal_outliers") tails = &c;
  }
  ASSERT_NE(tails, nullptr) << d["selected"].dump();
  EXPECT_GT((*tails)["params"]["probability"]["value"].get<double>(), 0.05);
  EXPECT_GT((*tails)["params"]["sigma_m"]["value"].get<double>(), 0.03);  // centimetres, not millimetres
  EXPECT_LT(d["remaining"]["failing_regions"].get<size_t>(), report["failing"].size() / 2) << d["remaining"].dump();
  fs::remove_all(out);
}

}  // namespace

namespace {

// The independent generator's room seen from a moving sensor (1 m/s, turning 20 degrees a second,
// 8 frames, seed 3) with `hidden` effects, diagnosed in map mode against os1-32-paper, without
// the room's mesh: the report's diagnosis.
void diagnose_moving_capture(const std::string& name, const std::string& hidden, nlohmann::json& diagnosis) {
  const fs::path dir = temp(name);
  const std::string generate = "/usr/bin/python3 " + kSource + "/tests/tools/independent_capture.py " + dir.string() +
                               " --frames 8 --seed 3 --velocity 1 0 0 --yaw-rate 20 " + hidden + " > /dev/null";
  ASSERT_EQ(std::system(generate.c_str()), 0) << generate;
  const fs::path out = dir / "map";
  const CliRun r = run_cli("compare --map --diagnose --capture " + (dir / "capture.pcap").string() + " --metadata " +
                           (dir / "metadata.json").string() + " --pose " + (dir / "pose.tum").string() +
                           " --profile os1-32-paper --out " + out.string() + " --no-plots");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  diagnosis = read_json(out / "report.json")["diagnosis"];
  fs::remove_all(dir);
}

// A moving capture the independent generator wrote (tests/tools/independent_capture.py: its own
// packets, radiometry and noise, from the protocol and physics documents alone), six walls of
// different reflectivity, with signal-dependent precision (E2) hidden: map mode, without the
// room's mesh, names E2 as the scene-based diagnosis does, with k near the generator's.
TEST(CompareMapIndependentCapture, MapModeNamesTheHiddenSignalDependentPrecision) {
  nlohmann::json diagnosis;
  ASSERT_NO_FATAL_FAILURE(diagnose_moving_capture(
      "map_independent_e2", "--snr-k 0.4 --wall-reflectivity 0.08 0.15 0.3 0.5 0.7 0.95", diagnosis));
  const auto& selected = diagnosis["selected"];
  ASSERT_FALSE(selected.empty()) << diagnosis.dump();
  EXPECT_EQ(selected[0]["effect"], "signal_precision");
  ASSERT_TRUE(selected[0]["params"].contains("k_m")) << selected[0].dump();
  EXPECT_NEAR(selected[0]["params"]["k_m"]["value"].get<double>(), 0.4, 0.06) << selected[0].dump();
}

// The generator's E2 tails (30 % of the weakest returns, fewer past 100 photons, 10 cm wider) on
// walls from 2 % to 90 % reflectivity: map mode names signal_outliers alone. Its three values trade
// against each other and the map's own error (probability 0.13, half at 389 photons, 7.4 cm here):
// the tails' width is asserted to the centimetre's order, not to its interval.
TEST(CompareMapIndependentCapture, MapModeNamesTheTailsOfWeakReturns) {
  nlohmann::json diagnosis;
  ASSERT_NO_FATAL_FAILURE(diagnose_moving_capture(
      "map_independent_tails",
      "--tail-probability 0.3 --tail-half-signal 100 --tail-sigma 0.1 --wall-reflectivity 0.02 0.05 0.1 0.3 0.6 0.9",
      diagnosis));
  const auto& selected = diagnosis["selected"];
  ASSERT_EQ(selected.size(), 1u) << diagnosis.dump();
  EXPECT_EQ(selected[0]["effect"], "signal_outliers");
  const double sigma = selected[0]["params"]["sigma_m"]["value"].get<double>();
  EXPECT_GT(sigma, 0.05);
  EXPECT_LT(sigma, 0.15);
}

// The same generator with two badly calibrated beams (E10: beam 40 reads 30 mm long, beam 10 20 mm
// short), as the real OS-1-128 sample has one: map mode names beam_calibration and puts the two
// beams' offsets first. Less than the scene's (which finds 30.1 and -19.7 mm): each return's
// reference surface is made of other frames' points of the beam itself and its neighbours, so it
// carries part of the beam's own offset, and the neighbours see a share of it with the other sign.
TEST(CompareMapIndependentCapture, MapModeNamesTwoBadlyCalibratedBeams) {
  nlohmann::json diagnosis;
  ASSERT_NO_FATAL_FAILURE(
      diagnose_moving_capture("map_independent_e10", "--beam-offset 40 0.03 --beam-offset 10 -0.02", diagnosis));
  const auto& selected = diagnosis["selected"];
  ASSERT_FALSE(selected.empty()) << diagnosis.dump();
  EXPECT_EQ(selected[0]["effect"], "beam_calibration");
  std::string longest, shortest;
  double most = 0.0, least = 0.0, others = 0.0;
  for (const auto& [name, p] : selected[0]["params"].items()) {
    if (name.rfind("offsets_m/", 0) != 0) continue;
    const double v = p["value"].get<double>();
    if (v > most) most = v, longest = name;
    if (v < least) least = v, shortest = name;
    if (name != "offsets_m/40" && name != "offsets_m/10") others = std::max(others, std::abs(v));
  }
  EXPECT_EQ(longest, "offsets_m/40");
  EXPECT_EQ(shortest, "offsets_m/10");
  EXPECT_GT(most, 0.6 * 0.03);
  EXPECT_LT(most, 1.1 * 0.03);
  EXPECT_LT(least, 0.5 * -0.02);
  EXPECT_GT(least, 1.1 * -0.02);
  EXPECT_LT(others, 0.4 * 0.03) << selected[0]["params"].dump();
}

}  // namespace

}  // namespace cli_compare_without_scene_test
