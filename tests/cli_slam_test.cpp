// The paper's experiment (lidar odometry on a recorded flight, scored by APE) as a user runs it:
// `record` the yard lap, `points` exports the frames, an Open3D odometry (tools/lidar-odometry.py,
// Debian's python3-open3d, not lidartwin code) tracks them, `ape` scores it against the recorded
// per-column ground truth. An ideal sensor must track the lap to centimetres once the odometry
// deskews with the column timestamps, and worse without. The first half of the lap (23.2 s: take-off,
// acceleration to 4 m/s, two banked turns) keeps CI's time down: APE 0.020 m deskewed, 0.071 m
// without; the whole lap (tools/slam-experiment.py) gave 0.048 and 0.213 m.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace cli_slam_test {

namespace fs = std::filesystem;

namespace {

int shell(const std::string& command) {
  const int status = std::system((command + " > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string lidartwin() { return LIDARTWIN_BINARY; }
std::string source(const std::string& path) { return std::string(LIDARTWIN_SOURCE_DIR) + "/" + path; }

double ape_rmse(const fs::path& dir, const std::string& estimate) {
  const fs::path out = dir / ("ape_" + estimate);
  EXPECT_EQ(shell(lidartwin() + " ape --reference " + (dir / "column_poses.tum").string() + " --estimate " +
                  (dir / estimate).string() + " --max-diff 0.001 --out " + out.string()),
            0);
  std::ifstream in(out / "ape.json");
  return nlohmann::json::parse(in)["rmse_m"].get<double>();
}

TEST(CliSlam, AnIdealSensorTracksHalfTheYardLapToCentimetresWhenDeskewed) {
  if (shell("/usr/bin/python3 -c 'import open3d'") != 0) {
    GTEST_SKIP() << "python3-open3d is not installed (tools/test installs it)";
  }
  const fs::path dir = fs::path(testing::TempDir()) / ("slam_" + std::to_string(getpid()));
  fs::remove_all(dir);
  ASSERT_EQ(
      shell(lidartwin() + " record --profile os1-32 --ideal --scene " + source("scenes/yard.glb") + " --trajectory " +
            source("scenes/yard_flight.tum") + " --mode 1024x10 --frames 232 --out " + dir.string()),
      0);
  ASSERT_EQ(shell(lidartwin() + " points --capture " + (dir / "capture.pcap").string() + " --metadata " +
                  (dir / "metadata.json").string() + " --out " + (dir / "frames.npz").string()),
            0);
  const std::string odometry =
      "/usr/bin/python3 " + source("tools/lidar-odometry.py") + " " + (dir / "frames.npz").string();
  ASSERT_EQ(shell(odometry + " --deskew --out " + (dir / "deskewed.tum").string()), 0);
  ASSERT_EQ(shell(odometry + " --out " + (dir / "raw.tum").string()), 0);
  const double deskewed = ape_rmse(dir, "deskewed.tum");
  const double raw = ape_rmse(dir, "raw.tum");
  std::printf("first half of the yard lap, ideal OS1-32, Open3D odometry: APE RMSE %.3f m deskewed, %.3f m without\n",
              deskewed, raw);
  EXPECT_LT(deskewed, 0.08);
  EXPECT_GT(raw, 1.5 * deskewed);
  fs::remove_all(dir);
}

}  // namespace

}  // namespace cli_slam_test
