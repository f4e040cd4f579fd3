// `lidartwin compare` on MOVING captures it did not write: tests/tools/independent_capture.py (written
// from the protocol doc and lidar-physics.md alone) casts every column of its box room from the
// pose at that column's own timestamp and writes the ground-truth trajectory as TUM knots, one per
// frame and one where the last frame ends. compare casts the capture's beams at each column's own
// time from the interpolated knots: if the two agree, the paper's profile fits; poses that are
// static, held for a frame or shifted by 2 ms must not. A second capture gives the six walls their
// own reflectivities: compare's per-reflectivity bins, the REFLECTIVITY channel and the spread of a
// signal-dependent noise (E2) must all follow the walls the scene says.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace cli_compare_moving_capture_test {

namespace fs = std::filesystem;

namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;
const std::string kGenerator = "/usr/bin/python3 " + kSource + "/tests/tools/independent_capture.py ";

struct CliRun {
  int code = -1;
  std::string out, err;
};

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Runs a shell command, capturing stdout and stderr.
CliRun run(const std::string& command) {
  static int calls = 0;
  const fs::path err =
      fs::path(testing::TempDir()) / ("moving_stderr_" + std::to_string(getpid()) + "_" + std::to_string(++calls));
  CliRun r;
  FILE* pipe = popen((command + " 2>" + err.string()).c_str(), "r");
  char buffer[4096];
  while (size_t n = fread(buffer, 1, sizeof buffer, pipe)) r.out.append(buffer, n);
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.err = slurp(err);
  fs::remove(err);
  return r;
}

CliRun lidartwin(const std::string& arguments) { return run(std::string(LIDARTWIN_BINARY) + " " + arguments); }

nlohmann::json read_json(const fs::path& path) { return nlohmann::json::parse(slurp(path)); }

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(testing::TempDir()) / ("moving_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  return dir;
}

// One TUM line: t tx ty tz qx qy qz qw.
std::vector<std::vector<double>> read_tum(const fs::path& path) {
  std::vector<std::vector<double>> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream fields(line);
    std::vector<double> v;
    for (double x; fields >> x;) v.push_back(x);
    if (!v.empty()) lines.push_back(v);
  }
  return lines;
}

void write_tum(const fs::path& path, const std::vector<std::vector<double>>& lines) {
  std::ofstream out(path);
  out.precision(17);
  for (const auto& v : lines) {
    for (size_t i = 0; i < v.size(); ++i) out << (i ? " " : "") << v[i];
    out << "\n";
  }
}

const nlohmann::json& summary(const nlohmann::json& report) { return report["summary"]; }

double nll_excess_se(const nlohmann::json& report) {
  const auto& s = summary(report);
  return (s["nll_per_pixel"].get<double>() - s["nll_expected"].get<double>()) / s["nll_se"].get<double>();
}

// 8 frames (0.8 s) moving forward at 1 m/s and turning at 20 deg/s: 0.8 m and 16 degrees, 10 cm and
// 2 degrees within each frame.
TEST(CompareMovingIndependentCapture, EveryColumnIsCastFromThePoseAtItsOwnTimestamp) {
  const fs::path dir = scratch("capture");
  const int frames = 8;
  const CliRun made = run(kGenerator + dir.string() + " --frames " + std::to_string(frames) +
                          " --seed 3 --velocity 1 0 0 --yaw-rate 20");
  ASSERT_EQ(made.code, 0) << made.err;

  // The ground truth: a knot at each frame's first column and one where the last frame ends, one
  // frame period apart, moving 0.1 m and turning 2 degrees from knot to knot.
  const auto knots = read_tum(dir / "pose.tum");
  ASSERT_EQ(knots.size(), static_cast<size_t>(frames + 1));
  for (size_t k = 1; k < knots.size(); ++k) {
    ASSERT_EQ(knots[k].size(), 8u);
    EXPECT_NEAR(knots[k][0] - knots[k - 1][0], 0.1, 1e-9);
    EXPECT_NEAR(knots[k][1] - knots[k - 1][1], 0.1, 1e-9);
    const double yaw = 2 * std::atan2(knots[k][6], knots[k][7]),
                 previous = 2 * std::atan2(knots[k - 1][6], knots[k - 1][7]);
    EXPECT_NEAR((yaw - previous) * 180 / std::numbers::pi, 2.0, 1e-9);
  }

  const std::string inputs = " --capture " + (dir / "capture.pcap").string() + " --metadata " +
                             (dir / "metadata.json").string() + " --scene " + (dir / "scene.gltf").string() +
                             " --profile os1-32-paper --no-plots --pixels";
  const auto compare = [&](const std::string& pose, const std::string& extra, const std::string& name) {
    const fs::path out = dir / name;
    const CliRun r = lidartwin("compare" + inputs + " --pose " + pose + extra + " --out " + out.string());
    EXPECT_EQ(r.code, 0) << r.err;
    return read_json(out / "report.json");
  };

  const nlohmann::json fit = compare((dir / "pose.tum").string(), "", "truth");
  const auto& s = summary(fit);
  EXPECT_EQ(s["pixels"], frames * 1024 * 64);
  EXPECT_EQ(s["returns"], frames * 1024 * 64);
  EXPECT_EQ(s["unexpected_returns"], 0);
  EXPECT_TRUE(fit["failing"].empty()) << fit["failing"][0]["sentence"];
  EXPECT_NEAR(s["nll_per_pixel"].get<double>(), s["nll_expected"].get<double>(), 4 * s["nll_se"].get<double>());
  EXPECT_NEAR(s["z"]["mean"].get<double>(), 0.0, 0.01);
  EXPECT_NEAR(s["z"]["std"].get<double>(), 1.0, 0.01);
  std::printf("  true trajectory: NLL %+.1f standard errors from its expectation\n", nll_excess_se(fit));

  // The knots span the capture on its own clock: the first is the first column's timestamp, the
  // last one column period after the last column's (as compare read them from the packets).
  const CliRun times =
      run("/usr/bin/python3 -c \"import numpy as np; t = np.load('" + (dir / "truth" / "pixels.npz").string() +
          "')['time_s']; print('%.9f %.9f' % (t.min(), t.max()))\"");
  ASSERT_EQ(times.code, 0) << times.err;
  double first = 0, last = 0;
  ASSERT_EQ(std::sscanf(times.out.c_str(), "%lf %lf", &first, &last), 2) << times.out;
  EXPECT_NEAR(knots.front()[0], first, 1e-6);
  EXPECT_NEAR(knots.back()[0], last + 0.1 / 1024, 1e-6);

  // A static sensor's pose (the first knot alone): the motion is seen everywhere.
  write_tum(dir / "static.tum", {knots.front()});
  const nlohmann::json still = compare((dir / "static.tum").string(), "", "static");
  EXPECT_FALSE(still["failing"].empty());
  EXPECT_GT(nll_excess_se(still), 100);
  std::printf("  static pose: NLL %+.1f standard errors, %zu failing regions\n", nll_excess_se(still),
              still["failing"].size());

  // Each frame cast from its first column's pose (held until the next knot): what a generator that
  // moved the sensor only between frames would match. The motion within a frame is seen.
  std::vector<std::vector<double>> held;
  for (size_t k = 0; k + 1 < knots.size(); ++k) {
    held.push_back(knots[k]);
    std::vector<double> hold = knots[k];
    hold[0] = knots[k + 1][0] - 1e-6;
    held.push_back(hold);
  }
  held.push_back(knots.back());
  write_tum(dir / "held.tum", held);
  const nlohmann::json stepped = compare((dir / "held.tum").string(), "", "held");
  EXPECT_FALSE(stepped["failing"].empty());
  EXPECT_GT(nll_excess_se(stepped), 100);
  std::printf("  poses held for a frame: NLL %+.1f standard errors, %zu failing regions\n", nll_excess_se(stepped),
              stepped["failing"].size());

  // The true trajectory 2 ms late (2 mm, 0.04 degrees; 20 of a frame's 1024 columns): the column
  // timing of the two agrees more closely than that. The last frame is left out, whose last columns
  // would fall past the last knot.
  const nlohmann::json late = compare((dir / "pose.tum").string(), " --time-offset 0.002 --frames 7", "late");
  EXPECT_FALSE(late["failing"].empty());
  EXPECT_GT(nll_excess_se(late), 6);
  std::printf("  trajectory 2 ms late: NLL %+.1f standard errors, %zu failing regions\n", nll_excess_se(late),
              late["failing"].size());
  fs::remove_all(dir);
}

TEST(CompareMovingIndependentCapture, TheGeneratorRefusesAMotionThatLeavesTheRoom) {
  const fs::path dir = scratch("leaves");
  // From 10 m at 3 m/s along +x: within 0.5 m of the wall x = 12 m after 0.5 s of the 0.8.
  const CliRun r = run(kGenerator + dir.string() + " --frames 8 --start 10 0 0 --velocity 3 0 0");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("the motion leaves the room: 0.5000 s after the first column"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("wall x = 12 m"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "capture.pcap"));
  fs::remove_all(dir);
}

// The six walls with their own reflectivities, one per bin of compare's reflectivity feature, and a
// signal-dependent precision (E2, k = 0.4 m x sqrt(photon)) hidden by the generator, so that a
// wall's range spread depends on its reflectivity. The profile: the paper's with the generator's
// radiometric constants and its E2 (both from truth.json), so the model is the generator's.
TEST(CompareMovingIndependentCapture, EachWallsReflectivityReachesTheScenesMaterialsAndTheRadiometry) {
  const fs::path dir = scratch("walls");
  const std::vector<double> rho = {0.08, 0.15, 0.3, 0.5, 0.7, 0.95};  // x_min x_max y_min y_max floor ceiling
  std::string walls, reversed;
  for (size_t i = 0; i < rho.size(); ++i) {
    walls += " " + std::to_string(rho[i]);
    reversed += " " + std::to_string(rho[rho.size() - 1 - i]);
  }
  // 2 m up, so that the ceiling is in the beams' view.
  const CliRun made = run(kGenerator + dir.string() + " --frames 6 --seed 4 --snr-k 0.4 --start 0 0 2" +
                          " --wall-reflectivity" + walls);
  ASSERT_EQ(made.code, 0) << made.err;
  // The same room with the reflectivities the other way round (its scene only).
  const CliRun other =
      run(kGenerator + (dir / "reversed").string() + " --frames 1 --start 0 0 2" + " --wall-reflectivity" + reversed);
  ASSERT_EQ(other.code, 0) << other.err;

  const nlohmann::json truth = read_json(dir / "truth.json");
  nlohmann::json profile = read_json(kSource + "/profiles/os1-32-paper.json");
  nlohmann::json chain = nlohmann::json::array();
  for (nlohmann::json effect : profile["effects"]) {
    if (effect["name"] == "radiometry") effect.update(truth["radiometry"]);
    chain.push_back(effect);
    if (effect["name"] == "range_noise_linear")
      chain.push_back({{"name", "signal_precision"}, {"k_m", truth["snr_k_m"]}});
  }
  profile["effects"] = chain;
  std::ofstream(dir / "profile.json") << profile.dump(1);

  const std::string inputs = " --capture " + (dir / "capture.pcap").string() + " --metadata " +
                             (dir / "metadata.json").string() + " --pose " + (dir / "pose.tum").string() +
                             " --profile " + (dir / "profile.json").string() + " --no-plots --pixels";
  const CliRun r = lidartwin("compare" + inputs + " --scene " + (dir / "scene.gltf").string() + " --out " +
                             (dir / "report").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json report = read_json(dir / "report" / "report.json");
  const auto& s = summary(report);
  EXPECT_EQ(s["returns"], 6 * 1024 * 64);
  EXPECT_TRUE(report["failing"].empty()) << report["failing"][0]["sentence"];
  EXPECT_NEAR(s["nll_per_pixel"].get<double>(), s["nll_expected"].get<double>(), 4 * s["nll_se"].get<double>());

  // One reflectivity bin per wall, each holding its wall's pixels, measured spread as predicted.
  std::set<double> bins;
  for (const auto& bin : report["bins"]) {
    if (bin["features"].size() != 1 || !bin["features"].contains("reflectivity")) continue;
    const double lo = bin["features"]["reflectivity"][0], hi = bin["features"]["reflectivity"][1];
    int holds = 0;
    for (const double wall : rho) holds += lo <= 100 * wall && 100 * wall < hi;
    EXPECT_EQ(holds, 1) << bin.dump();
    bins.insert(lo);
    // Within 4 standard errors: the spread ratio's is about 1 / sqrt(2 n), the bias's sigma / sqrt(n).
    const double n = bin["pixels"].get<double>();
    EXPECT_GT(n, 1000) << bin.dump();
    EXPECT_NEAR(bin["spread_ratio"].get<double>(), 1.0, 4 / std::sqrt(2 * n)) << bin.dump();
    EXPECT_NEAR(bin["bias_m"]["measured"].get<double>(), bin["bias_m"]["predicted"].get<double>(),
                4 * bin["spread_m"]["predicted"].get<double>() / std::sqrt(n))
        << bin.dump();
    for (const char* test : {"bias", "spread", "detection", "outliers"})
      EXPECT_GT(bin["p_value"][test].get<double>(), 0.01) << test << ": " << bin.dump();
    std::printf("  reflectivity %g-%g %%: %d pixels, spread %.1f mm (model %.1f mm)\n", lo, hi,
                bin["pixels"].get<int>(), 1e3 * bin["spread_m"]["measured"].get<double>(),
                1e3 * bin["spread_m"]["predicted"].get<double>());
  }
  EXPECT_EQ(bins.size(), rho.size());

  // The REFLECTIVITY byte the generator wrote is round(100 rho cos(incidence)) of the wall it hit:
  // against each pixel's material reflectivity and incidence as compare cast them from the scene.
  const fs::path check = dir / "reflectivity_check.py";
  std::ofstream(check) << "import sys, numpy as np\n"
                          "d = np.load(sys.argv[1])\n"
                          "model = 100 * d['material_reflectivity'] * np.cos(np.radians(d['incidence_deg']))\n"
                          "off = np.abs(d['reflectivity'] - model)\n"
                          "print(len(np.unique(d['material_reflectivity'])), (off <= 0.51).mean(), off.max())\n";
  const CliRun numbers = run("/usr/bin/python3 " + check.string() + " " + (dir / "report" / "pixels.npz").string());
  ASSERT_EQ(numbers.code, 0) << numbers.err;
  int materials = 0;
  double within = 0, worst = 0;
  ASSERT_EQ(std::sscanf(numbers.out.c_str(), "%d %lf %lf", &materials, &within, &worst), 3) << numbers.out;
  EXPECT_EQ(materials, 6);
  EXPECT_GT(within, 0.999) << "worst " << worst;

  // The scene with the walls' reflectivities reversed: the expected signal, hence the E2 spread, is
  // wrong on every wall, and compare sees it.
  const CliRun wrong = lidartwin("compare" + inputs + " --scene " + (dir / "reversed" / "scene.gltf").string() +
                                 " --out " + (dir / "reversed_report").string());
  ASSERT_EQ(wrong.code, 0) << wrong.err;
  const nlohmann::json misfit = read_json(dir / "reversed_report" / "report.json");
  ASSERT_FALSE(misfit["failing"].empty());
  EXPECT_EQ(misfit["failing"][0]["quantity"], "spread");
  EXPECT_GT(nll_excess_se(misfit), 50);
  std::printf("  walls reversed: NLL %+.1f standard errors, %zu failing regions\n", nll_excess_se(misfit),
              misfit["failing"].size());
  fs::remove_all(dir);
}

}  // namespace

}  // namespace cli_compare_moving_capture_test
