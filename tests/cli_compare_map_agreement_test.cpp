// `compare --map` proven on captures whose answer is known (issue 23): a drive through the plant
// with the incidence effect (E4) hidden, one through the yard with signal-dependent precision (E2)
// hidden, both recorded by `lidartwin record`, and a moving capture of the independent generator
// (tests/tools/independent_capture.py) with E2 hidden. Each is compared with the profile that
// lacks the hidden effect twice, with its scene and without (map mode, the frames placed by the
// true trajectory; also registered, and within each frame), and they must say the same: the spread
// per range and reflectivity bin, the regions that fail, the effect the diagnosis names.
//
// The two reports bin different returns (map mode keeps those on smooth surfaces the other frames
// saw: mostly the ground, at grazing incidence, where E2 and E4 are strongest), so their bins of
// one range hold different mixes of incidence and signal. The spreads are therefore compared on the
// returns both judged (tests/tools/same_returns_spread.py, from the two pixels.npz), binned by the
// scene's range and reflectivity; the reports' own bins are compared where the profile is the
// recording's, whose spread ratio is 1 whatever the mix.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"
#include "support/table_profile.h"

namespace cli_compare_map_agreement_test {

namespace fs = std::filesystem;

namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;
const std::string kPython = "/usr/bin/python3 ";

using lidartwin::test::CliRun;
using lidartwin::test::run_cli;

// Bins holding fewer returns than this are not compared: their spread ratio is not known to 5 %
// (a ratio from n returns has a relative standard error of 1/sqrt(2n) only for Gaussian residuals;
// the hidden effects make them heavier-tailed, and a bin's mix varies with its few surfaces).
constexpr size_t kMinInliers = 10000;
// The spreads of the same returns are compared from half that: the two modes' ratios share the
// returns' own noise, so their quotient varies far less than either (the yard's 13-20 m and 20-35 m
// bins, about 6,000 returns each, the ground at 80-85 degrees).
constexpr size_t kMinSameInliers = 5000;

nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// The shipped os1-64 profile with its table effects only (radiometry, the datasheet's sigma(r),
// limits, quantization: support/table_profile.h) and, when given, one effect more: what a capture
// is recorded with.
fs::path os1_64_with(const fs::path& dir, const std::string& name, const nlohmann::json& extra) {
  std::ifstream in(kSource + "/profiles/os1-64.json");
  nlohmann::json profile = nlohmann::json::parse(in);
  table_profiles::keep_table_effects(profile["effects"]);
  // The datasheet's radiometry, not the real OS-1-128 sample's sunlit ambient (2571 photons): the
  // hidden E2's k of 0.2 m is sized for it (at that ambient it would make most returns outliers).
  for (auto& effect : profile["effects"]) {
    if (effect["name"] == "radiometry") effect = {{"name", "radiometry"}};
  }
  if (!extra.is_null()) {
    auto& effects = profile["effects"];
    const auto limits =
        std::find_if(effects.begin(), effects.end(), [](const auto& e) { return e["name"] == "range_limits"; });
    effects.insert(limits, extra);
  }
  const fs::path path = dir / (name + ".json");
  std::ofstream(path) << profile.dump(2);
  return path;
}

struct Judged {
  std::string hidden;         // the effect the capture has and the profile lacks
  nlohmann::json scene, map;  // the two report.json
  nlohmann::json same;        // same_returns_spread.py on them
  nlohmann::json registered;  // the same for map mode with the frames registered to each other
  nlohmann::json within;      // the same for map mode within each frame (--within-frame)
};

class MapAgreement : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::path(testing::TempDir()) / ("map_agreement_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    table_ = os1_64_with(dir_, "os1-64", nullptr);
    // 2.5 m/s and 10 deg/s, 1.7 m above the ground (a car's roof), 6 frames (1.5 m).
    record("plant", "plant.glb", "12 9", "19.5 9", os1_64_with(dir_, "plant_e4", {{"name", "incidence"}}), "incidence");
    record("yard", "yard.glb", "-4 -18", "3.5 -18",
           os1_64_with(dir_, "yard_e2", {{"name", "signal_precision"}, {"k_m", 0.2}}), "signal_precision");
    generate_independent();
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static void record(const std::string& name, const std::string& scene, const std::string& from, const std::string& to,
                     const fs::path& profile, const std::string& hidden) {
    const fs::path out = dir_ / name;
    std::ofstream(dir_ / (name + ".tum"))
        << "0 " << from << " 1.7 0 0 0 1\n3 " << to << " 1.7 0 0 0.0871557 0.9961947\n";
    const CliRun r =
        run_cli("record --profile " + profile.string() + " --scene " + kSource + "/scenes/" + scene + " --trajectory " +
                (dir_ / (name + ".tum")).string() + " --uptime-s 0 --frames 6 --seed 5 --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    judge(name,
          " --capture " + (out / "capture.pcap").string() + " --metadata " + (out / "metadata.json").string() +
              " --pose " + (out / "poses.tum").string() + " --profile " + table_.string(),
          " --scene " + kSource + "/scenes/" + scene, hidden);
    // The frames registered to each other instead of placed by the trajectory (no --diagnose).
    const fs::path registered = dir_ / (name + "_registered");
    const CliRun m =
        run_cli("compare --map --no-plots --pixels --capture " + (out / "capture.pcap").string() + " --metadata " +
                (out / "metadata.json").string() + " --profile " + table_.string() + " --out " + registered.string());
    ASSERT_EQ(m.exit_code, 0) << m.output;
    judged_[name].registered = same_returns(name + "_scene", name + "_registered");
  }

  static nlohmann::json same_returns(const std::string& scene, const std::string& map) {
    const fs::path same = dir_ / (map + "_same.json");
    const std::string script = kPython + kSource + "/tests/tools/same_returns_spread.py " + (dir_ / scene).string() +
                               " " + (dir_ / map).string() + " > " + same.string();
    EXPECT_EQ(std::system(script.c_str()), 0) << script;
    return read_json(same);
  }

  // Six walls of different reflectivity, moving at 1 m/s and 20 deg/s, spread following the SNR.
  static void generate_independent() {
    const fs::path out = dir_ / "independent";
    const std::string generate = kPython + kSource + "/tests/tools/independent_capture.py " + out.string() +
                                 " --frames 6 --seed 3 --velocity 1 0 0 --yaw-rate 20 --snr-k 0.4"
                                 " --wall-reflectivity 0.08 0.15 0.3 0.5 0.7 0.95 > /dev/null";
    ASSERT_EQ(std::system(generate.c_str()), 0) << generate;
    judge("independent",
          " --capture " + (out / "capture.pcap").string() + " --metadata " + (out / "metadata.json").string() +
              " --pose " + (out / "pose.tum").string() + " --profile os1-32-paper",
          " --scene " + (out / "scene.gltf").string(), "signal_precision");
  }

  // compare with the scene and without it (--map, with --diagnose), and the spreads on the same
  // returns. (The scene's own diagnosis names each of these hidden effects in cli_compare_test and
  // cli_compare_moving_capture_test; here map mode's is held to the truth, which costs CI a third of
  // the time.)
  static void judge(const std::string& name, const std::string& inputs, const std::string& scene,
                    const std::string& hidden) {
    Judged& j = judged_[name];
    j.hidden = hidden;
    for (const bool map : {false, true}) {
      const fs::path out = dir_ / (name + (map ? "_map" : "_scene"));
      const CliRun r = run_cli(std::string("compare --no-plots --pixels") + (map ? " --map --diagnose" : scene) +
                               inputs + " --out " + out.string());
      ASSERT_EQ(r.exit_code, 0) << r.output;
      (map ? j.map : j.scene) = read_json(out / "report.json");
    }
    j.same = same_returns(name + "_scene", name + "_map");
    // Each frame on its own: a reference from the frame's other returns (no trajectory needed).
    const fs::path within = dir_ / (name + "_within");
    const std::string frames_only =
        inputs.substr(0, inputs.find(" --pose ")) + inputs.substr(inputs.find(" --profile "));
    const CliRun w =
        run_cli("compare --map --within-frame --no-plots --pixels" + frames_only + " --out " + within.string());
    ASSERT_EQ(w.exit_code, 0) << w.output;
    EXPECT_TRUE(read_json(within / "report.json")["inputs"]["map"]["within_frame"].get<bool>());
    j.within = same_returns(name + "_scene", name + "_within");
  }

  static inline fs::path dir_, table_;
  static inline std::map<std::string, Judged> judged_;
};

// The single-feature bins of `feature` in a report, by their lower edge.
std::map<double, nlohmann::json> bins_of(const nlohmann::json& report, const std::string& feature) {
  std::map<double, nlohmann::json> out;
  for (const auto& bin : report["bins"]) {
    if (bin["features"].size() == 1 && bin["features"].contains(feature)) {
      out[bin["features"][feature][0].get<double>()] = bin;
    }
  }
  return out;
}

// Whether a report lists the spread of a single-feature bin among its failing regions.
bool spread_fails(const nlohmann::json& report, const std::string& feature, double lower) {
  for (const auto& f : report["failing"]) {
    if (f["quantity"] == "spread" && f["features"].size() == 1 && f["features"].contains(feature) &&
        f["features"][feature][0].get<double>() == lower) {
      return true;
    }
  }
  return false;
}

// Per range and reflectivity bin, on the returns both judged, map mode's spread ratio (the
// reference's own variance taken out) is the scene's within 5 %, the ground at 80-85 degrees
// beyond 13 m included (docs/compare-report.md, "References without a scene").
// Map mode's spread ratio over the scene's, per bin of `feature` holding min_inliers or more;
// returns how many were compared.
size_t expect_agreement(const std::string& name, const nlohmann::json& same, const std::string& feature,
                        size_t min_inliers = kMinSameInliers) {
  size_t compared = 0;
  for (const auto& bin : same[feature]) {
    if (bin["inliers"].get<size_t>() < min_inliers) continue;
    const double ratio = bin["map"].get<double>() / bin["scene"].get<double>();
    EXPECT_NEAR(ratio, 1.0, 0.05) << name << " " << feature << " " << bin.dump();
    ++compared;
  }
  return compared;
}

void spread_per_range_and_reflectivity_bin_agrees(const std::map<std::string, Judged>& judged) {
  for (const auto& [name, j] : judged) {
    EXPECT_GE(expect_agreement(name, j.same, "range") + expect_agreement(name, j.same, "reflectivity"), 4u)
        << name << ": " << j.same.dump();
  }
}

// The incidence map mode estimates from its surfaces (on which E4's spread and the material's
// reflectivity rest) is the scene's within half a degree, the median of every range bin, on the
// ground at grazing incidence, where E4's spread changes by a tenth per degree, and on the
// independent capture's walls at 15-50 degrees: gathered by its points' measured positions, a patch
// tilted towards the sensor by their noise along the surface (plant 8-13 m: -1.5 degrees; the
// independent capture's 13-20 m: -1.3).
void incidence_agrees(const std::map<std::string, Judged>& judged) {
  for (const auto& [name, j] : judged) {
    size_t compared = 0;
    for (const auto& bin : j.same["range"]) {
      if (bin["inliers"].get<size_t>() < kMinSameInliers) continue;
      EXPECT_NEAR(bin["incidence_deg_map_less_scene"].get<double>(), 0.0, 0.5) << name << " " << bin.dump();
      ++compared;
    }
    EXPECT_GE(compared, 2u) << name << ": " << j.same.dump();
  }
}

// Map mode's spreads in millimetres say what its ratios say: both weigh the returns alike (they
// read "0.0 mm against 0.0 mm" for a bin 3.8 times too wide when a few returns whose reference was
// most of their residual decided the millimetres).
void spreads_in_millimetres_agree_with_the_ratios(const std::map<std::string, Judged>& judged) {
  for (const auto& [name, j] : judged) {
    size_t compared = 0;
    for (const auto& bin : j.map["bins"]) {
      if (bin["inliers"].get<size_t>() < 100) continue;
      const double predicted = bin["spread_m"]["predicted"].get<double>();
      EXPECT_GT(predicted, 1e-3) << name << " " << bin.dump();
      EXPECT_NEAR(bin["spread_m"]["measured"].get<double>() / predicted, bin["spread_ratio"].get<double>(), 1e-6)
          << name << " " << bin.dump();
      ++compared;
    }
    EXPECT_GT(compared, 50u) << name;
  }
}

// With the frames registered to each other the same holds per range bin of kMinInliers. Per
// reflectivity bin it does not yet: where the profile is right (the plant's 40-60 %, walls at
// near-normal incidence) the registration's error (a few millimetres, not in the reference's
// variance) shows, 1.10 times the scene's, and so it does at 1-2 m (1.14, 7,600 returns;
// docs/compare-report.md).
void with_registered_frames_the_spread_per_range_bin_agrees(const std::map<std::string, Judged>& judged) {
  for (const auto& [name, j] : judged) {
    if (j.registered.is_null()) continue;  // the independent capture is judged with its trajectory only
    EXPECT_GE(expect_agreement(name + " (registered)", j.registered, "range", kMinInliers), 2u)
        << name << ": " << j.registered.dump();
  }
}

// Within each frame (--within-frame, what map mode does with a capture of one frame, as most
// published samples are) the same holds per range and reflectivity bin: the plant's within 1.5 %,
// the yard's within 3 %, the independent capture's within 4.2 % (its darkest walls). Not compared:
// the yard's darkest ground (3,900 returns at 5-10 %, 1.17 times the scene's: noisy returns at 76
// degrees, where a frame's few points under-count the reference's error), under kMinSameInliers.
void within_a_frame_the_spread_per_range_and_reflectivity_bin_agrees(const std::map<std::string, Judged>& judged) {
  for (const auto& [name, j] : judged) {
    EXPECT_GE(expect_agreement(name + " (within each frame)", j.within, "range") +
                  expect_agreement(name + " (within each frame)", j.within, "reflectivity"),
              4u)
        << name << ": " << j.within.dump();
  }
}

// Where the scene-based comparison finds the spread failing, so does map mode, and the reverse:
// every range and reflectivity bin both judge on enough returns.
void the_same_regions_fail(const std::map<std::string, Judged>& judged) {
  for (const auto& [name, j] : judged) {
    size_t compared = 0, failing = 0;
    for (const std::string feature : {"range", "reflectivity"}) {
      const auto scene = bins_of(j.scene, feature), map = bins_of(j.map, feature);
      for (const auto& [lower, bin] : scene) {
        const auto other = map.find(lower);
        if (other == map.end() || bin["inliers"].get<size_t>() < kMinInliers ||
            other->second["inliers"].get<size_t>() < kMinInliers) {
          continue;
        }
        const bool in_scene = spread_fails(j.scene, feature, lower);
        EXPECT_EQ(spread_fails(j.map, feature, lower), in_scene) << name << " " << feature << " from " << lower;
        ++compared;
        failing += in_scene;
      }
    }
    EXPECT_GE(compared, 3u) << name;
    EXPECT_GE(failing, 1u) << name << ": the hidden effect fails no region with the scene";
  }
}

// What a diagnosis names: its candidates by their gain (ranked), those it keeps (selected), and
// the noise laws it would replace (parameter_misfit[].replacement).
struct Named {
  std::string first;
  std::set<std::string> kept;
};
Named named(const nlohmann::json& diagnosis) {
  Named n;
  if (!diagnosis["ranked"].empty()) n.first = diagnosis["ranked"][0]["effect"];
  for (const auto& c : diagnosis["selected"]) n.kept.insert(c["effect"]);
  for (const auto& m : diagnosis["parameter_misfit"]) {
    if (m.contains("replacement")) n.kept.insert(m["replacement"]["effect"]);
  }
  return n;
}

// Without the scene the diagnosis ranks the hidden effect first, as it does with the scene. It
// also keeps it on the plant and the independent capture, but on the yard it keeps E2's tails
// (at half the returns, their bound) and incidence in E2's stead (known, docs/compare-report.md):
// not asserted.
void the_hidden_effect_is_named_as_with_the_scene(const std::map<std::string, Judged>& judged) {
  for (const auto& [name, j] : judged) {
    const Named map = named(j.map["diagnosis"]);
    EXPECT_EQ(map.first, j.hidden) << name << " (map): " << j.map["diagnosis"]["ranked"].dump();
    if (name != "yard") {
      EXPECT_TRUE(map.kept.count(j.hidden)) << name << " (map): " << j.map["diagnosis"]["selected"].dump();
    }
  }
}

// One test, so that its captures are recorded and compared once: ctest runs each test in a
// process of its own, and the suite's fixture would be rebuilt for every one (about 3.5 minutes).
TEST_F(MapAgreement, ScenesAndMapsSpreadsFailingRegionsAndDiagnosesAgree) {
  {
    SCOPED_TRACE("the spread per range and reflectivity bin agrees with the scene's on the same returns");
    spread_per_range_and_reflectivity_bin_agrees(judged_);
  }
  {
    SCOPED_TRACE("the incidence agrees with the scene's on the same returns");
    incidence_agrees(judged_);
  }
  {
    SCOPED_TRACE("map mode's spreads in millimetres agree with its ratios");
    spreads_in_millimetres_agree_with_the_ratios(judged_);
  }
  {
    SCOPED_TRACE("with registered frames the spread per range bin agrees");
    with_registered_frames_the_spread_per_range_bin_agrees(judged_);
  }
  {
    SCOPED_TRACE("within each frame the spread per range and reflectivity bin agrees");
    within_a_frame_the_spread_per_range_and_reflectivity_bin_agrees(judged_);
  }
  {
    SCOPED_TRACE("the same regions fail");
    the_same_regions_fail(judged_);
  }
  {
    SCOPED_TRACE("the hidden effect is named as with the scene");
    the_hidden_effect_is_named_as_with_the_scene(judged_);
  }
}

}  // namespace

}  // namespace cli_compare_map_agreement_test
