// `lidartwin serve --profile UNIT.json`: a twin of a real unit, made from the metadata the unit
// served. For every sample metadata file, the daemon is started as a user would, its metadata is
// fetched over HTTP, and what a client sees is checked against the unit's file as it is written
// (nested FW 3.x or flat FW 2.x keys), not against our parser's reading of it.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/packet/data_format.h"

namespace lidartwin::e2e::unit_twin_test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kSamples = fs::path(LIDARTWIN_TEST_DATA) / "ouster-samples";

std::vector<std::string> sample_metadata_files() {
  std::vector<std::string> files;
  for (const fs::path& dir : {kSamples, kSamples / "metadata"}) {
    for (const auto& entry : fs::directory_iterator(dir)) {
      if (entry.path().extension() == ".json") files.push_back(fs::relative(entry.path(), kSamples).string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

// A key of the unit's file where its layout keeps it: nested under `section`, or at the top level
// (flat FW 2.x files; their data format is "data_format").
const json* unit_key(const json& unit, const std::string& section, const std::string& key) {
  const bool nested = unit.contains("sensor_info");
  const std::string stored = !nested && section == "lidar_data_format" ? "data_format" : section;
  const json* parent = &unit;
  if (nested || stored == "data_format") {
    const auto it = unit.find(stored);
    if (it == unit.end() || !it->is_object()) return nullptr;
    parent = &*it;
  }
  const auto it = parent->find(key);
  return it == parent->end() ? nullptr : &*it;
}

std::string text_of(const json* value) {
  if (value == nullptr) return "";
  return value->is_string() ? value->get<std::string>() : value->dump();
}

// The shipped profile a unit's product line names, as a user reads the README: "OS-1-128" ->
// os1-128, "OS-0-32-U1" -> os0-32; nullopt when there is none or the file's beams differ.
std::optional<std::string> expected_family(const json& unit) {
  static const std::regex line(R"(OS-([012])-(\d+)(-\w+)?)");
  std::smatch match;
  const std::string prod_line = text_of(unit_key(unit, "sensor_info", "prod_line"));
  if (!std::regex_match(prod_line, match, line)) return std::nullopt;
  const std::string family = "os" + match[1].str() + "-" + match[2].str();
  if (!fs::exists(fs::path(LIDARTWIN_SOURCE_DIR) / "profiles" / (family + ".json"))) return std::nullopt;
  const json* angles = unit_key(unit, "beam_intrinsics", "beam_altitude_angles");
  if (angles == nullptr || angles->size() != std::stoul(match[2].str())) return std::nullopt;
  return family;
}

std::vector<std::string> twin_args(const fs::path& unit_file) { return room_args(unit_file.string()); }

class UnitTwin : public ::testing::TestWithParam<std::string> {};

TEST_P(UnitTwin, ServesTheUnitsIdentityIntrinsicsAndConfig) {
  const fs::path file = kSamples / GetParam();
  std::ifstream in(file);
  const json unit = json::parse(in);
  if (!expected_family(unit)) {
    // Not a unit with a shipped family (a reduced config without prod_line, a 16-beam OS-1, ...):
    // refused, naming the file and the product line. (A daemon that starts instead is stopped.)
    try {
      Daemon daemon("127.0.0.1", 0, twin_args(file));
      ADD_FAILURE() << "serve started a twin of " << file << ", expected a refusal";
    } catch (const std::runtime_error& refused) {
      const std::string output = refused.what();
      EXPECT_NE(output.find(file.string()), std::string::npos) << output;
      EXPECT_NE(output.find("prod_line"), std::string::npos) << output;
    }
    return;
  }
  Daemon daemon("127.0.0.1", 0, twin_args(file));
  json served, firmware;
  {  // closed before the daemon stops, which would otherwise wait out the keep-alive
    SensorHttp http(daemon.address(), daemon.http_port());
    served = http.get_json("sensor/metadata");
    firmware = http.get_json("system/firmware");
  }

  // Identity and firmware as the unit reports them (where its file has them: some FW 1.x/2.x files
  // lack build_date).
  for (const char* key : {"prod_line", "prod_pn", "prod_sn", "build_rev", "image_rev", "build_date"}) {
    if (const json* value = unit_key(unit, "sensor_info", key)) {
      EXPECT_EQ(served.at("sensor_info").at(key), text_of(value)) << key;
    }
  }
  if (const json* image_rev = unit_key(unit, "sensor_info", "image_rev")) {
    EXPECT_EQ(firmware.at("fw"), text_of(image_rev));
  }

  // Every angle and every transform the file gives, to the last digit; what it leaves out, the SDK's
  // defaults (protocol doc 3.1), which the unit's parser fills in.
  const Metadata defaults = load_metadata(file);
  const json& beams = served.at("beam_intrinsics");
  for (const char* key : {"beam_altitude_angles", "beam_azimuth_angles"}) {
    EXPECT_EQ(beams.at(key).get<std::vector<double>>(),
              unit_key(unit, "beam_intrinsics", key)->get<std::vector<double>>())
        << key;
  }
  const auto expect_intrinsic = [&](const std::string& section, const std::string& key, const json& served_value,
                                    const json& default_value) {
    const json* given = unit_key(unit, section, key);
    EXPECT_EQ(served_value, given ? *given : default_value) << section << "/" << key;
  };
  expect_intrinsic("beam_intrinsics", "lidar_origin_to_beam_origin_mm", beams.at("lidar_origin_to_beam_origin_mm"),
                   defaults.beams.lidar_origin_to_beam_origin_mm);
  expect_intrinsic("beam_intrinsics", "beam_to_lidar_transform", beams.at("beam_to_lidar_transform"),
                   defaults.beams.beam_to_lidar);
  expect_intrinsic("lidar_intrinsics", "lidar_to_sensor_transform",
                   served.at("lidar_intrinsics").at("lidar_to_sensor_transform"), defaults.beams.lidar_to_sensor);
  expect_intrinsic("imu_intrinsics", "imu_to_sensor_transform",
                   served.at("imu_intrinsics").at("imu_to_sensor_transform"), defaults.beams.imu_to_sensor);

  // The config the unit ran: its lidar mode, packet profile (LEGACY when a FW 2.x file names none)
  // and columns per packet. A profile we cannot encode (FW 3.2 zone profiles) is the one exception.
  EXPECT_EQ(served.at("config_params").at("lidar_mode"), text_of(unit_key(unit, "config_params", "lidar_mode")));
  const json& format = served.at("lidar_data_format");
  const std::string unit_profile = text_of(unit_key(unit, "lidar_data_format", "udp_profile_lidar"));
  if (unit_profile.empty() || udp_profile_lidar_from_string(unit_profile)) {
    EXPECT_EQ(format.at("udp_profile_lidar"), unit_profile.empty() ? "LEGACY" : unit_profile);
  }
  if (const json* columns = unit_key(unit, "lidar_data_format", "columns_per_packet")) {
    EXPECT_EQ(format.at("columns_per_packet"), *columns);
  }
  EXPECT_EQ(format.at("pixels_per_column"), unit_key(unit, "beam_intrinsics", "beam_altitude_angles")->size());
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

INSTANTIATE_TEST_SUITE_P(Samples, UnitTwin, ::testing::ValuesIn(sample_metadata_files()),
                         [](const ::testing::TestParamInfo<std::string>& param) {
                           std::string name = param.param;
                           for (char& c : name) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return name;
                         });

// Flags still choose: --serial-number and --lidar-mode over the unit's, the unit's packet profile
// and firmware kept.
TEST(UnitTwinFlags, OverrideTheUnitsSerialAndMode) {
  const fs::path file = kSamples / "metadata" / "3_0_1_os-122246000293-128.json";
  auto args = twin_args(file);
  args.insert(args.end(), {"--serial-number", "987654321012", "--lidar-mode", "512x10"});
  Daemon daemon("127.0.0.1", 0, args);
  json served;
  {
    SensorHttp http(daemon.address(), daemon.http_port());
    served = http.get_json("sensor/metadata");
  }
  const Metadata unit = load_metadata(file);
  EXPECT_EQ(served.at("sensor_info").at("prod_sn"), "987654321012");
  EXPECT_EQ(served.at("sensor_info").at("build_rev"), unit.sensor_info.build_rev);
  EXPECT_EQ(served.at("config_params").at("lidar_mode"), "512x10");
  EXPECT_EQ(served.at("lidar_data_format").at("udp_profile_lidar"), to_string(unit.format.udp_profile_lidar));
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

// The packets name the unit too (4.3): a client that keeps only its sensor's packets, by prod_sn
// and initialization_id as the SDK does, assembles complete scans from the twin.
TEST(UnitTwinPackets, CarryTheUnitsSerialNumber) {
  const fs::path file = kSamples / "metadata" / "3_0_1_os-122246000293-128.json";
  UdpSocket lidar;
  Daemon daemon("127.0.0.1", 0, twin_args(file));
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  ASSERT_EQ(metadata.sensor_info.prod_sn, "122246000293");
  ScanBatcher batcher(metadata.format, SensorIds{metadata.sensor_info.initialization_id, 122246000293u});
  expect_complete_scans(receive_scans(lidar, batcher, 1, std::chrono::seconds(20)), metadata, 1);
  EXPECT_EQ(batcher.counts().foreign, 0u);
}

}  // namespace
}  // namespace lidartwin::e2e::unit_twin_test
