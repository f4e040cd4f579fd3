// `lidartwin record --rig FILE` (issue 26): a capture per sensor of the shipped example rig
// (rigs/vehicle.json), each with its own metadata and ground truth, all on one time base: at every
// column timestamp, each sensor's recorded pose is the vehicle's carried by that sensor's mounting.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/pose/pose.h"
#include "support/pose_inverse.h"

namespace lidartwin::cli_record_rig_test {
namespace {

namespace fs = std::filesystem;

const std::string kSource = LIDARTWIN_SOURCE_DIR;

int run(const std::string& args) {
  return std::system((std::string(LIDARTWIN_BINARY) + " " + args + " >/dev/null 2>&1").c_str());
}

TEST(RecordRig, EachSensorIsRecordedFromItsMountingOnOneTimeBase) {
  const fs::path out = fs::path(testing::TempDir()) / ("record_rig_" + std::to_string(getpid()));
  fs::remove_all(out);
  ASSERT_EQ(run("record --rig rigs/vehicle.json --scene " + kSource + "/scenes/yard.glb --trajectory " + kSource +
                "/scenes/yard_flight.tum --frames 2 --seed 4 --out " + out.string()),
            0);
  const nlohmann::json rig = nlohmann::json::parse(std::ifstream(kSource + "/rigs/vehicle.json"));
  const auto mount_of = [&](const nlohmann::json& sensor) {
    std::string text;
    for (const auto& v : sensor["mount"]) text += std::to_string(v.get<double>()) + " ";
    return parse_pose(text);
  };
  const nlohmann::json& roof_entry = rig["sensors"][0];
  ASSERT_EQ(roof_entry["name"], "roof");
  const std::vector<StampedPose> roof = Trajectory::load_tum(out / "roof" / "column_poses.tum").samples();
  ASSERT_EQ(roof.size(), 2u * 1024u);
  const Pose vehicle_from_roof = mount_of(roof_entry);
  std::set<std::string> serials;
  std::set<uint32_t> init_ids;
  for (const auto& entry : rig["sensors"]) {
    const fs::path dir = out / entry["name"].get<std::string>();
    ASSERT_TRUE(fs::exists(dir / "capture.pcap")) << dir;
    const nlohmann::json metadata = nlohmann::json::parse(std::ifstream(dir / "metadata.json"));
    serials.insert(metadata["sensor_info"]["prod_sn"].get<std::string>());
    init_ids.insert(metadata["sensor_info"]["initialization_id"].get<uint32_t>());
    const std::vector<StampedPose> own = Trajectory::load_tum(dir / "column_poses.tum").samples();
    ASSERT_EQ(own.size(), roof.size()) << dir;
    const Pose roof_from_sensor = test::inverse(vehicle_from_roof) * mount_of(entry);
    double worst_m = 0.0, worst_rad = 0.0;
    for (size_t i = 0; i < own.size(); ++i) {
      ASSERT_EQ(own[i].time_s, roof[i].time_s) << dir << " column " << i;  // one time base
      const Pose expected = roof[i].pose * roof_from_sensor;
      worst_m = std::max(worst_m, (own[i].pose.translation - expected.translation).norm());
      worst_rad = std::max(worst_rad, own[i].pose.rotation.angularDistance(expected.rotation));
    }
    EXPECT_LT(worst_m, 1e-6) << dir;  // the TUM files' 9 decimals
    EXPECT_LT(worst_rad, 1e-6) << dir;
  }
  EXPECT_EQ(serials.size(), rig["sensors"].size()) << "each sensor its own serial number";
  EXPECT_EQ(init_ids.size(), rig["sensors"].size()) << "each sensor its own seed, so its own session";
  fs::remove_all(out);
}

TEST(RecordRig, ABadSensorIsRefusedBeforeAnythingIsRecorded) {
  const fs::path dir = fs::path(testing::TempDir()) / ("record_bad_rig_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "rig.json") << R"({"sensors": [
      {"name": "roof", "profile": "os1-128", "address": "127.0.0.2"},
      {"name": "left", "profile": "os0-32", "address": "127.0.0.3", "lidar_mode": "4096x5"}]})";
  const std::string command = std::string(LIDARTWIN_BINARY) + " record --rig " + (dir / "rig.json").string() +
                              " --scene " + kSource + "/scenes/yard.glb --pose '0 0 2 0 0 0 1' --out " +
                              (dir / "out").string() + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[512];
  while (fgets(buffer, sizeof buffer, pipe)) output += buffer;
  EXPECT_NE(pclose(pipe), 0) << output;
  EXPECT_NE(output.find("sensor \"left\""), std::string::npos) << output;
  EXPECT_NE(output.find("4096x5"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(dir / "out" / "roof")) << "nothing recorded";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lidartwin::cli_record_rig_test
