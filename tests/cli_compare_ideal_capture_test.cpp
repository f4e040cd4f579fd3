// `compare` casts a capture's beams as `record` cast them (issue 25: one forward path): the pixel
// table and the renderer call the same cast stage (frame/cast_stage.h), so an --ideal recording of
// a moving, turning sensor, compared with its own scene and trajectory, has every return at its
// ideal range on the wire's step, in every column of every frame, and every pixel the scene hits
// within the profile's range window returned. A column cast from another pose (the frame's first
// column's, a column's time early), another reach or another frame would be centimetres off.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"

namespace cli_compare_ideal_capture_test {

namespace fs = std::filesystem;

namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;

using lidartwin::test::CliRun;
using lidartwin::test::run_cli;

TEST(CompareIdealCapture, EveryReturnOfAMovingSensorLiesAtTheRangeCompareCasts) {
  const fs::path dir = fs::path(testing::TempDir()) / ("ideal_capture_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  // 2.5 m/s and 10 deg/s through the plant, 1.7 m above the ground: a column's time (98 us) moves
  // the sensor 0.24 mm and turns it 1e-3 deg, a frame 25 cm and 1 deg.
  std::ofstream(dir / "drive.tum") << "0 12 9 1.7 0 0 0 1\n3 19.5 9 1.7 0 0 0.0871557 0.9961947\n";
  const fs::path capture = dir / "capture";
  const CliRun recorded =
      run_cli("record --ideal --profile os1-64 --scene " + kSource + "/scenes/plant.glb" + " --trajectory " +
              (dir / "drive.tum").string() + " --uptime-s 0 --frames 3 --seed 1 --out " + capture.string());
  ASSERT_EQ(recorded.exit_code, 0) << recorded.output;
  const fs::path report = dir / "report";
  const CliRun compared =
      run_cli("compare --no-plots --pixels --capture " + (capture / "capture.pcap").string() + " --metadata " +
              (capture / "metadata.json").string() + " --pose " + (capture / "poses.tum").string() + " --scene " +
              kSource + "/scenes/plant.glb --profile os1-64 --out " + report.string());
  ASSERT_EQ(compared.exit_code, 0) << compared.output;
  const fs::path residuals = dir / "residuals.json";
  const std::string script =
      "/usr/bin/python3 " + kSource + "/tests/tools/ideal_residuals.py " + report.string() + " > " + residuals.string();
  ASSERT_EQ(std::system(script.c_str()), 0) << script;
  std::ifstream in(residuals);
  const nlohmann::json r = nlohmann::json::parse(in);

  EXPECT_EQ(r["frames"], 3);
  EXPECT_EQ(r["columns"], 1024);
  EXPECT_GT(r["returns"].get<int>(), 150000) << r.dump();  // most of 3 x 1024 x 64 pixels see the plant
  EXPECT_EQ(r["beyond_half_a_step"], 0) << r.dump();
  EXPECT_LT(r["largest_difference_m"].get<double>(), 0.00052) << r.dump();  // half of RNG19's 1 mm, in floats
  EXPECT_EQ(r["returns_without_a_hit"], 0) << r.dump();
  EXPECT_EQ(r["hits_inside_without_a_return"], 0) << r.dump();
  fs::remove_all(dir);
}

}  // namespace

}  // namespace cli_compare_ideal_capture_test
