// `lidartwin record --trajectory-end` (issue 26): past a trajectory's last pose a capture holds it,
// loops, or stops there, as `serve` does; by default one that closes loops and one that does not
// holds. Checked on the ground truth record writes (poses.tum: each frame's first column).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "lidartwin/pose/pose.h"
#include "support/cli_run.h"

namespace lidartwin::cli_record_trajectory_end_test {
namespace {

namespace fs = std::filesystem;

const std::string kSource = LIDARTWIN_SOURCE_DIR;

// An open flight: 1 m along x in 0.25 s, from t = 0.
fs::path open_trajectory(const fs::path& dir) {
  const fs::path path = dir / "open.tum";
  std::ofstream(path) << "0 0 0 1.5 0 0 0 1\n0.25 1 0 1.5 0 0 0 1\n";
  return path;
}

struct Recorded {
  test::CliRun run;
  std::vector<StampedPose> frame_starts;  // poses.tum: frame k's first column, then the end of the last
};

Recorded record(const std::string& name, const std::string& end_flag) {
  const fs::path dir = fs::path(testing::TempDir()) / ("record_end_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path out = dir / name;
  fs::remove_all(out);
  Recorded r;
  r.run = test::run_cli("record --profile os1-32 --mode 512x10 --scene " + kSource + "/scenes/plant.glb --trajectory " +
                        open_trajectory(dir).string() + end_flag + " --frames 5 --uptime-s 0 --out " + out.string());
  if (r.run.exit_code == 0) r.frame_starts = Trajectory::load_tum(out / "poses.tum").samples();
  return r;
}

TEST(RecordTrajectoryEnd, AnOpenTrajectoryHoldsItsLastPoseByDefault) {
  const Recorded r = record("default", "");
  ASSERT_EQ(r.run.exit_code, 0) << r.run.output;
  EXPECT_NE(r.run.output.find("at its end the trajectory holds its last pose (it does not close"), std::string::npos)
      << r.run.output;
  ASSERT_EQ(r.frame_starts.size(), 6u);
  EXPECT_NEAR(r.frame_starts[1].pose.translation.x(), 0.4, 1e-9);  // 0.1 s in
  for (size_t k = 3; k < 6; ++k) {                                 // 0.3 s and later: at the last pose
    EXPECT_NEAR(r.frame_starts[k].pose.translation.x(), 1.0, 1e-9) << "frame " << k;
  }
}

TEST(RecordTrajectoryEnd, LoopStartsTheFlightAgain) {
  const Recorded r = record("loop", " --trajectory-end loop");
  ASSERT_EQ(r.run.exit_code, 0) << r.run.output;
  ASSERT_EQ(r.frame_starts.size(), 6u);
  EXPECT_NEAR(r.frame_starts[3].pose.translation.x(), 0.2, 1e-9);  // 0.3 s: 0.05 s into the second lap
}

TEST(RecordTrajectoryEnd, StopEndsTheCaptureWhereTheTrajectoryEnds) {
  const Recorded r = record("stop", " --trajectory-end stop");
  ASSERT_EQ(r.run.exit_code, 0) << r.run.output;
  EXPECT_NE(r.run.output.find("recorded 2 frames"), std::string::npos) << r.run.output;
  EXPECT_NE(r.run.output.find("the trajectory ended there (--trajectory-end stop)"), std::string::npos);
  ASSERT_EQ(r.frame_starts.size(), 3u);  // two frames, 0.2 s of the 0.25 s flight
  EXPECT_NEAR(r.frame_starts[2].pose.translation.x(), 0.8, 1e-9);
}

TEST(RecordTrajectoryEnd, ABadValueIsRefusedNamingTheFlag) {
  const Recorded r = record("bad", " --trajectory-end bounce");
  EXPECT_NE(r.run.exit_code, 0);
  EXPECT_NE(r.run.output.find("--trajectory-end"), std::string::npos) << r.run.output;
}

}  // namespace
}  // namespace lidartwin::cli_record_trajectory_end_test
