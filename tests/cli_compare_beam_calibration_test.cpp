// E10 as the diagnosis finds it: a hall capture recorded with per-beam range offsets drawn for one
// unit (beam_calibration's unit_seed), compared with `lidartwin compare --diagnose` against the
// profile without them. The diagnosis names beam_calibration (E10) first, fits each beam's offset
// and scale in closed form, keeps those BIC keeps (the offsets, not the scales: the unit has none),
// and the 95 % intervals cover the unit's true values (taken from the effect itself: its predicted
// bias at range 0 is the beam's offset).
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "support/table_profile.h"

namespace lidartwin::cli_compare_beam_calibration_test {
namespace {

namespace fs = std::filesystem;

const std::string kSource = LIDARTWIN_SOURCE_DIR;
const nlohmann::json kHidden = {{"name", "beam_calibration"}, {"offset_sigma_m", 0.01}, {"unit_seed", 3}};

int run(const std::string& arguments) {
  const int status = std::system((std::string(LIDARTWIN_BINARY) + " " + arguments + " > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CompareBeamCalibration, TheDiagnosisNamesPerBeamOffsetsAndFitsEveryBeam) {
  const fs::path dir = fs::path(testing::TempDir()) / ("compare_e10_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path profile = table_profiles::table_profile("os1-64");
  nlohmann::json hidden = nlohmann::json::parse(std::ifstream(profile));
  auto& effects = hidden["effects"];
  auto limits = std::find_if(effects.begin(), effects.end(), [](const auto& e) { return e["name"] == "range_limits"; });
  effects.insert(limits, kHidden);
  std::ofstream(dir / "e10.json") << hidden.dump();
  const std::string hall = kSource + "/scenes/calibration_hall.glb";
  ASSERT_EQ(run("record --profile " + (dir / "e10.json").string() + " --scene " + hall + " --trajectory " + kSource +
                "/scenes/calibration_hall_static.tum --frames 20 --seed 5 --out " + (dir / "capture").string()),
            0);
  ASSERT_EQ(run("compare --capture " + (dir / "capture").string() + " --scene " + hall + " --profile " +
                profile.string() + " --no-plots --diagnose --out " + (dir / "report").string()),
            0);
  const nlohmann::json diagnosis = nlohmann::json::parse(std::ifstream(dir / "report" / "report.json"))["diagnosis"];
  EXPECT_EQ(diagnosis["verdict"], "missing effect");
  ASSERT_EQ(diagnosis["ranked"][0]["effect"], "beam_calibration") << diagnosis["ranked"].dump(1);
  EXPECT_EQ(diagnosis["ranked"][0]["catalogue"], "E10");
  ASSERT_EQ(diagnosis["selected"].size(), 1u) << diagnosis["selected"].dump(1);
  EXPECT_TRUE(diagnosis["unexplained"].empty()) << diagnosis["unexplained"].dump(1);

  // The unit's true values, from the hidden effect itself.
  const EffectChain truth = EffectChain::from_json(nlohmann::json::array({kHidden}), "test");
  const auto& params = diagnosis["selected"][0]["params"];
  int offsets_kept = 0, offsets_covered = 0, scales_kept = 0;
  for (uint16_t b = 0; b < 64; ++b) {
    IdealReturn at_zero;
    at_zero.beam = b;
    const double offset = truth.predict(at_zero, {}).bias_m;
    const std::string name = "offsets_m/" + std::to_string(b);
    scales_kept += params.contains("scales/" + std::to_string(b));
    if (!params.contains(name)) {  // left out: too close to 0 to be evidence
      EXPECT_LT(std::abs(offset), 0.001) << "beam " << b;
      continue;
    }
    const auto& fitted = params[name];
    ++offsets_kept;
    offsets_covered += fitted["ci95"][0].get<double>() <= offset && offset <= fitted["ci95"][1].get<double>();
    EXPECT_NEAR(fitted["value"].get<double>(), offset, 0.002) << "beam " << b;
  }
  std::printf("offsets kept for %d of 64 beams, %d of whose intervals cover the unit's value; %d scales kept\n",
              offsets_kept, offsets_covered, scales_kept);
  EXPECT_GE(offsets_kept, 60);
  // 95 % intervals: about 61 of 64 (at least 56 holds with probability 0.998).
  EXPECT_GE(offsets_covered, offsets_kept - 8);
  // The unit has no scales: BIC keeps one where chi^2 gains more than ln n (p about 3e-4 per beam).
  EXPECT_LE(scales_kept, 2);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lidartwin::cli_compare_beam_calibration_test
