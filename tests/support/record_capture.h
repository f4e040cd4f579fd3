#pragma once
// For the `lidartwin record` acceptance tests: run the binary, decode what it wrote, and the SDK's
// XYZ projection (protocol doc 7.1) transcribed independently of the caster.
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <sys/wait.h>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan_batcher.h"
#include "lidartwin/pcap/pcap.h"
#include "support/table_profile.h"

namespace lidartwin::test {

// Runs `lidartwin <arguments>`, returns its exit code.
inline int run_lidartwin(const std::string& arguments) {
  const std::string command = std::string(LIDARTWIN_BINARY) + " " + arguments;
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The calibration hall from its static pose (scenes/calibration_hall_static.tum): the scene the
// effects' fingerprint tests record.
inline std::string hall_scene() { return std::string(LIDARTWIN_SOURCE_DIR) + "/scenes/calibration_hall.glb"; }
inline constexpr const char* kHallPose = "0 0 4 0 0 0 1";

using table_profiles::keep_table_effects;
using table_profiles::table_profile;

// profiles/<shipped>.json with its table effects only (keep_table_effects), its chain then changed
// by `edit(effects)`, written to the test's temporary directory as <name>.json.
template <class Edit>
std::filesystem::path edited_profile(const std::string& shipped, const std::string& name, Edit edit) {
  std::ifstream in(std::string(LIDARTWIN_SOURCE_DIR) + "/profiles/" + shipped + ".json");
  nlohmann::json profile = nlohmann::json::parse(in);
  keep_table_effects(profile.at("effects"));
  edit(profile.at("effects"));
  const auto path = std::filesystem::path(testing::TempDir()) / (name + ".json");
  std::ofstream(path) << profile.dump(2);
  return path;
}

// `lidartwin record <options>` of the hall into the temporary directory <name>, which it returns.
inline std::filesystem::path record_hall(const std::string& name, const std::string& options) {
  const auto dir = std::filesystem::path(testing::TempDir()) / name;
  std::filesystem::remove_all(dir);
  const std::string args = "record --scene " + hall_scene() + " --pose \"" + kHallPose + "\" " + options + " --out " +
                           dir.string() + " > /dev/null 2>&1";
  EXPECT_EQ(run_lidartwin(args), 0) << args;
  return dir;
}

// The beam intrinsics read straight from metadata.json's nested sections (3.1).
struct SdkIntrinsics {
  std::vector<double> altitude_deg, azimuth_deg;
  std::array<double, 16> beam_to_lidar{}, lidar_to_sensor{};
  int columns = 0;

  static SdkIntrinsics load(const std::filesystem::path& metadata_json) {
    std::ifstream in(metadata_json);
    const auto doc = nlohmann::json::parse(in);
    SdkIntrinsics s;
    const auto& bi = doc.at("beam_intrinsics");
    s.altitude_deg = bi.at("beam_altitude_angles").get<std::vector<double>>();
    s.azimuth_deg = bi.at("beam_azimuth_angles").get<std::vector<double>>();
    s.beam_to_lidar = bi.at("beam_to_lidar_transform").get<std::array<double, 16>>();
    s.lidar_to_sensor = doc.at("lidar_intrinsics").at("lidar_to_sensor_transform").get<std::array<double, 16>>();
    s.columns = doc.at("lidar_data_format").at("columns_per_frame").get<int>();
    return s;
  }

  // 7.1: unit vector u and offset o (mm, lidar frame), both through lidar_to_sensor.
  void lut(int row, int col, Eigen::Vector3d& direction, Eigen::Vector3d& offset_m) const {
    const double pi = std::numbers::pi;
    const double encoder = 2 * pi - col * 2 * pi / columns;
    const double azimuth = -azimuth_deg[static_cast<size_t>(row)] * pi / 180;
    const double altitude = altitude_deg[static_cast<size_t>(row)] * pi / 180;
    const auto& B = beam_to_lidar;
    const double n = B[11] == 0 ? B[3] : std::hypot(B[3], B[11]);
    const Eigen::Vector3d u(std::cos(encoder + azimuth) * std::cos(altitude),
                            std::sin(encoder + azimuth) * std::cos(altitude), std::sin(altitude));
    const Eigen::Vector3d o(B[3] * std::cos(encoder) - n * u.x(), B[3] * std::sin(encoder) - n * u.y(),
                            B[11] - n * u.z());
    const auto& T = lidar_to_sensor;
    Eigen::Matrix3d R;
    R << T[0], T[1], T[2], T[4], T[5], T[6], T[8], T[9], T[10];
    direction = R * u;
    offset_m = 0.001 * (R * o + Eigen::Vector3d(T[3], T[7], T[11]));
  }
  Eigen::Vector3d point(int row, int col, double range_mm) const {
    Eigen::Vector3d d, o;
    lut(row, col, d, o);
    return range_mm * 0.001 * d + o;
  }
  double beam_offset_m() const {
    const auto& B = beam_to_lidar;
    return 0.001 * (B[11] == 0 ? B[3] : std::hypot(B[3], B[11]));
  }
};

// Every frame of a capture's lidar packets (port 7502), decoded with the metadata it came with.
struct DecodedCapture {
  Metadata metadata;
  std::map<uint32_t, Scan> frames;  // by frame_id
  size_t lidar_packets = 0;
  size_t imu_packets = 0;
  std::vector<ImuSample> imu;  // LEGACY IMU packets (port 7503), decoded
};

inline DecodedCapture decode_capture(const std::filesystem::path& dir) {
  DecodedCapture capture;
  capture.metadata = load_metadata(dir / "metadata.json");
  ScanBatcher batcher(capture.metadata.format);
  const auto keep = [&capture](std::optional<BatchedFrame> frame) {
    if (frame) capture.frames.emplace(frame->frame_id, std::move(frame->scan));
  };
  for (const UdpDatagram& datagram : read_pcap(dir / "capture.pcap")) {
    if (datagram.dst_port == 7503) {
      ++capture.imu_packets;
      if (const auto sample = decode_legacy_imu(datagram.payload)) capture.imu.push_back(*sample);
    }
    if (datagram.dst_port != 7502) continue;
    ++capture.lidar_packets;
    keep(batcher.add(datagram.payload));
  }
  keep(batcher.flush());
  const auto& counts = batcher.counts();
  if (counts.batched != capture.lidar_packets) {
    throw std::runtime_error(std::to_string(capture.lidar_packets - counts.batched) + " lidar packets not batched (" +
                             batcher.first_error() + ")");
  }
  return capture;
}

// poses.tum rows (t, pose), read without the pose module.
struct GroundTruthPose {
  double time_s;
  Eigen::Quaterniond rotation;
  Eigen::Vector3d translation;
};
inline std::vector<GroundTruthPose> read_poses(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::vector<GroundTruthPose> poses;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    double t, x, y, z, qx, qy, qz, qw;
    row >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
    poses.push_back({t, Eigen::Quaterniond(qw, qx, qy, qz).normalized(), Eigen::Vector3d(x, y, z)});
  }
  return poses;
}

}  // namespace lidartwin::test
