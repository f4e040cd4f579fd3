// metadata: every real metadata file parses as the SDK reads it, round-trips through the nested
// FW 3.1 document, and bad input fails with the file and JSON path named.
#include "lidartwin/metadata/metadata.h"

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "lidartwin/error.h"

namespace lidartwin {
namespace {

const std::filesystem::path kData = LIDARTWIN_TEST_DATA;
const std::filesystem::path kSamples = kData / "ouster-samples";
// The complete example of protocol doc 3.5 (OS-1-64, FW 3.1), copied verbatim from the doc.
const std::filesystem::path kDocExample = kData / "protocol_doc" / "metadata_fw31_os1_64.json";

nlohmann::json read_json(const std::filesystem::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Every *.json of the sample set, relative to kSamples: 21 next to the pcaps, 26 in metadata/.
std::vector<std::string> sample_files() {
  std::vector<std::string> files;
  for (const auto& dir : {kSamples, kSamples / "metadata"}) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.path().extension() == ".json") files.push_back(entry.path().lexically_relative(kSamples).string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(MetadataSampleSet, HasAllFortySevenFiles) { EXPECT_EQ(sample_files().size(), 47u); }

class MetadataSample : public testing::TestWithParam<std::string> {};

TEST_P(MetadataSample, ParsesIntoAConsistentDescription) {
  const Metadata m = load_metadata(kSamples / GetParam());
  const LidarDataFormat& f = m.format;
  const size_t h = static_cast<size_t>(f.pixels_per_column);
  EXPECT_EQ(m.beams.altitude_deg.size(), h);
  EXPECT_EQ(m.beams.azimuth_deg.size(), h);
  EXPECT_EQ(f.pixel_shift_by_row.size(), h);
  EXPECT_TRUE(f.columns_per_frame == 512 || f.columns_per_frame == 1024 || f.columns_per_frame == 2048);
  EXPECT_GE(f.column_window[0], 0);
  EXPECT_LT(f.column_window[1], f.columns_per_frame);
  for (const char* key : {"lidar_mode", "udp_dest", "udp_port_lidar", "udp_port_imu"}) {
    EXPECT_TRUE(m.config_params.contains(key)) << key;
  }
}

TEST_P(MetadataSample, RoundTripsThroughTheNestedDocument) {
  const Metadata m = load_metadata(kSamples / GetParam());
  const nlohmann::json nested = to_nested_json(m);
  for (const char* section : {"sensor_info", "beam_intrinsics", "imu_intrinsics", "lidar_intrinsics", "config_params",
                              "lidar_data_format", "calibration_status", "imu_data_format"}) {
    EXPECT_TRUE(nested.at(section).is_object()) << section;
  }
  EXPECT_TRUE(nested["sensor_info"]["prod_sn"].is_string());
  EXPECT_TRUE(nested["sensor_info"]["initialization_id"].is_number_integer());
  EXPECT_EQ(parse_metadata(nested, "nested"), m);
}

INSTANTIATE_TEST_SUITE_P(Samples, MetadataSample, testing::ValuesIn(sample_files()),
                         [](const testing::TestParamInfo<std::string>& param) {
                           std::string name = param.param;
                           for (char& c : name) c = std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
                           return name;
                         });

// Expected values below are read off the files and the sample README, not from the parser.
TEST(Metadata, ReadsALegacyFlatFile) {
  const Metadata m = load_metadata(kSamples / "OS-0-32-U1_v2.2.0_1024x10.json");
  EXPECT_EQ(m.sensor_info.prod_line, "OS-0-32-U1");
  EXPECT_EQ(m.sensor_info.prod_sn, "992137000142");
  EXPECT_EQ(m.sensor_info.initialization_id, 9599938u);
  EXPECT_EQ(m.format.udp_profile_lidar, UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual);
  EXPECT_EQ(m.format.udp_profile_imu, UdpProfileImu::kLegacy);
  EXPECT_EQ(m.format.pixels_per_column, 32);
  EXPECT_EQ(m.format.columns_per_frame, 1024);
  EXPECT_EQ(m.format.fps, 10);
  EXPECT_DOUBLE_EQ(m.beams.lidar_origin_to_beam_origin_mm, 27.67);
  EXPECT_DOUBLE_EQ(m.beams.altitude_deg[0], 43.88);
  EXPECT_EQ(m.config_params["udp_port_lidar"], 7502);
  EXPECT_EQ(m.config_params["udp_port_imu"], 7503);
  EXPECT_TRUE(m.lidar_enabled());
}

TEST(Metadata, FillsTheSdkDefaultsForTheReducedConfig) {
  // lidar_mode and the two angle arrays only (protocol doc 3.2).
  const Metadata m = load_metadata(kSamples / "OS-1-64_sensor_config_reduced.json");
  EXPECT_EQ(m.format.pixels_per_column, 64);  // no prod_line: the default format's 64
  EXPECT_EQ(m.format.columns_per_packet, 16);
  EXPECT_EQ(m.format.udp_profile_lidar, UdpProfileLidar::kLegacy);
  EXPECT_EQ(m.format.header_type, HeaderType::kStandard);
  EXPECT_EQ(m.format.column_window, (std::array<int, 2>{0, 1023}));
  EXPECT_EQ(m.format.fps, 10);
  // Gen-1 shifts of default_data_format at 1024 columns: 18, 12, 6, 0 repeating.
  EXPECT_EQ(std::vector<int>(m.format.pixel_shift_by_row.begin(), m.format.pixel_shift_by_row.begin() + 5),
            (std::vector<int>{18, 12, 6, 0, 18}));
  EXPECT_DOUBLE_EQ(m.beams.lidar_origin_to_beam_origin_mm, 12.163);  // no product line: Gen 1
  EXPECT_EQ(m.beams.beam_to_lidar, (Mat4{1, 0, 0, 12.163, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}));
  EXPECT_EQ(m.beams.lidar_to_sensor, (Mat4{-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 36.18, 0, 0, 0, 1}));
  EXPECT_EQ(m.beams.imu_to_sensor, (Mat4{1, 0, 0, 6.253, 0, 1, 0, -11.775, 0, 0, 1, 7.645, 0, 0, 0, 1}));
  EXPECT_EQ(m.config_params["udp_dest"], "127.0.0.1");
  EXPECT_EQ(m.config_params["lidar_mode"], "1024x10");
}

TEST(Metadata, OusterStudioReducedConfigIsA2048ColumnSensor) {
  const Metadata m = load_metadata(kSamples / "metadata/ouster-studio-reduced-config-v1.json");
  EXPECT_EQ(m.format.columns_per_frame, 2048);
  EXPECT_EQ(m.format.pixels_per_column, 64);
  EXPECT_EQ(m.format.pixel_shift_by_row[0], 36);
}

TEST(Metadata, DefaultsTheBeamOriginByProductLine) {
  // FW 1.12 flat OS-1-64 file without lidar_origin_to_beam_origin_mm: the SDK's OS-1 default.
  const Metadata m = load_metadata(kSamples / "metadata/1_12_os1-991937000062-64_legacy.json");
  EXPECT_DOUBLE_EQ(m.beams.lidar_origin_to_beam_origin_mm, 15.806);
  EXPECT_DOUBLE_EQ(m.beams.beam_to_lidar[3], 15.806);
}

TEST(Metadata, TreatsFirmware112ErrorStringsAsMissingSections) {
  // FW 1.12 stored "error: Command not recognized." as lidar_data_format and calibration_status,
  // and called udp_dest udp_ip.
  const Metadata m = load_metadata(kSamples / "metadata/1_12_os1-991913000010-64.json");
  EXPECT_EQ(m.format.columns_per_frame, 1024);
  EXPECT_EQ(m.format.udp_profile_lidar, UdpProfileLidar::kLegacy);
  EXPECT_EQ(m.calibration_status, nlohmann::json::object());
  EXPECT_EQ(m.config_params["udp_dest"], "169.254.91.92");
  EXPECT_EQ(m.config_params["udp_port_lidar"], 60823);
}

TEST(Metadata, OldReducedChannelFilesKeepTheir64Pixels) {
  // FW 1.12/1.13 OS-1-16/32 files list 64 angles and no data format: that FW sent 64 pixels per
  // column. The current SDK rejects these files (the beam count of the product line differs); we
  // take 64, the size of the data. FW 1.14 files have a data format and 16 angles.
  for (const char* file :
       {"metadata/1_12_os1-991937000062-16A0_legacy.json", "metadata/1_13_os1-991937000062-16A0_legacy.json",
        "metadata/1_13_os1-991937000062-32A02_legacy.json"}) {
    EXPECT_EQ(load_metadata(kSamples / file).format.pixels_per_column, 64) << file;
  }
  EXPECT_EQ(load_metadata(kSamples / "metadata/1_14_beta_os1-991937000062-16A0_legacy.json").format.pixels_per_column,
            16);
}

TEST(Metadata, ReadsColumnWindowsAndModes) {
  EXPECT_EQ(load_metadata(kSamples / "windowed_frame2_0.json").format.column_window, (std::array<int, 2>{370, 85}));
  const Metadata col_win = load_metadata(kSamples / "metadata/2_0_0_os1-992008000494-128_col_win_legacy.json");
  EXPECT_EQ(col_win.format.column_window, (std::array<int, 2>{2014, 2036}));
  EXPECT_EQ(col_win.format.columns_per_frame, 2048);
  // Named 1024x10, but the sample README says 1024x20.
  const Metadata os2 = load_metadata(kSamples / "OS-2-32-U0_v2.0.0_1024x10.json");
  EXPECT_EQ(os2.format.fps, 20);
}

TEST(Metadata, DerivesTheFusaHeaderFromTheProfile) {
  const Metadata m = load_metadata(kSamples / "OS-1-128_767798045_1024x10_20230712_120049.json");
  EXPECT_EQ(m.format.udp_profile_lidar, UdpProfileLidar::kFusaRng15Rfl8Nir8Dual);
  EXPECT_EQ(m.format.header_type, HeaderType::kFusa);
  EXPECT_FALSE(to_nested_json(m)["lidar_data_format"].contains("header_type"));  // FW 3.1 has no key
}

TEST(Metadata, EmptyUdpDestTurnsLidarOff) {
  // FW 2.1.2 nested file with udp_dest "" and no profile keys: LEGACY implied, lidar off.
  const Metadata m = load_metadata(kSamples / "metadata/2_1_2_os1-991913000010-64.json");
  EXPECT_EQ(m.format.udp_profile_lidar, UdpProfileLidar::kLegacy);
  EXPECT_FALSE(m.lidar_enabled());
}

TEST(Metadata, AcceptsAnUndecodableProfileOnlyWithLidarOff) {
  const Metadata m = load_metadata(kSamples / "imu_zm_no_lidar_0.json");
  EXPECT_FALSE(m.lidar_enabled());  // udp_port_lidar 0
  EXPECT_EQ(m.undecodable_lidar_profile, "RNG19_RFL8_SIG16_NIR16_ZONE16");
  EXPECT_EQ(m.format.udp_profile_imu, UdpProfileImu::kAccel32Gyro32Nmea);
  EXPECT_EQ(m.format.imu_measurements_per_packet, 8);
  EXPECT_EQ(m.format.imu_packets_per_frame, 8);
  EXPECT_EQ(to_nested_json(m)["lidar_data_format"]["udp_profile_lidar"], "RNG19_RFL8_SIG16_NIR16_ZONE16");

  nlohmann::json enabled = read_json(kSamples / "imu_zm_no_lidar_0.json");
  enabled["config_params"]["udp_port_lidar"] = 7502;
  EXPECT_THROW(parse_metadata(enabled, "zm.json"), InputError);
}

TEST(Metadata, ServesTheProtocolDocExampleUnchanged) {
  const nlohmann::json example = read_json(kDocExample);
  EXPECT_EQ(to_nested_json(parse_metadata(example, "example")), example);
}

std::string error_of(const nlohmann::json& document, const std::string& source = "OS-1-64.json") {
  try {
    parse_metadata(document, source);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(MetadataErrors, NamesFilePathAndExpectedCount) {
  nlohmann::json doc = read_json(kDocExample);
  doc["beam_intrinsics"]["beam_altitude_angles"].erase(63);
  EXPECT_EQ(error_of(doc),
            "OS-1-64.json: /beam_intrinsics/beam_altitude_angles: must be 64 numbers, got an array of 63");
}

TEST(MetadataErrors, NamesEachMissingSectionOfAPartialSet) {
  nlohmann::json doc = read_json(kDocExample);
  doc.erase("lidar_data_format");
  doc.erase("calibration_status");
  const std::string error = error_of(doc);
  EXPECT_NE(error.find("OS-1-64.json"), std::string::npos) << error;
  EXPECT_NE(error.find("missing /lidar_data_format, /calibration_status"), std::string::npos) << error;
  EXPECT_EQ(error.find("/sensor_info"), std::string::npos) << error;
}

TEST(MetadataErrors, LegacyErrorsNameTheTopLevelKey) {
  nlohmann::json doc = read_json(kSamples / "OS-0-32-U1_v2.2.0_1024x10.json");
  doc["beam_azimuth_angles"][3] = "x";
  EXPECT_EQ(error_of(doc, "flat.json"), "flat.json: /beam_azimuth_angles/3: must be a number, got a string \"x\"");
  doc = read_json(kSamples / "OS-0-32-U1_v2.2.0_1024x10.json");
  doc["data_format"]["column_window"] = {0, 1024};
  EXPECT_NE(error_of(doc).find("/data_format/column_window/1: must be an integer in [0, 1023]"), std::string::npos)
      << error_of(doc);
}

struct BadValue {
  const char* pointer;
  nlohmann::json value;
  const char* expected_in_message;
};

TEST(MetadataErrors, RejectsMistypedAndOutOfRangeValues) {
  const BadValue cases[] = {
      {"/sensor_info/prod_sn", 122201000123, "/sensor_info/prod_sn: must be a string"},
      {"/sensor_info/prod_sn", "12-34", "/sensor_info/prod_sn: must be a string of decimal digits"},
      {"/sensor_info/initialization_id", "7", "/sensor_info/initialization_id: must be an integer"},
      {"/sensor_info/initialization_id", 1 << 24,
       "/sensor_info/initialization_id: must be an integer in [0, 16777215]"},
      {"/config_params/lidar_mode", "1000x10", "/config_params/lidar_mode: must be one of 512x10"},
      {"/config_params/udp_port_lidar", 70000, "/config_params/udp_port_lidar: must be an integer in [0, 65535]"},
      {"/config_params/azimuth_window", {0}, "/config_params/azimuth_window: must be [start, end]"},
      {"/lidar_data_format/udp_profile_lidar", "RNG99", "must be one of LEGACY, RNG19_RFL8_SIG16_NIR16"},
      {"/lidar_data_format/udp_profile_imu", 3, "/lidar_data_format/udp_profile_imu: must be a string"},
      {"/lidar_data_format/header_type", "FANCY", "must be STANDARD or FUSA"},
      {"/lidar_data_format/pixels_per_column", 0, "must be an integer in [1, 128]"},
      {"/lidar_data_format/pixel_shift_by_row", "none", "must be an array of integers"},
      {"/beam_intrinsics/beam_to_lidar_transform",
       {1, 0},
       "beam_to_lidar_transform: must be 16 numbers, got an array of 2"},
      {"/beam_intrinsics/lidar_origin_to_beam_origin_mm", nullptr, "must be a number, got null"},
      {"/lidar_intrinsics", "text", nullptr},  // a string section is FW 1.12's error reply: allowed
      {"/imu_intrinsics", 5, "/imu_intrinsics: must be an object"},
  };
  for (const BadValue& c : cases) {
    nlohmann::json doc = read_json(kDocExample);
    doc[nlohmann::json::json_pointer(c.pointer)] = c.value;
    const std::string error = error_of(doc);
    if (c.expected_in_message == nullptr) {
      EXPECT_EQ(error, "(no error)") << c.pointer;
    } else {
      EXPECT_NE(error.find(c.expected_in_message), std::string::npos) << c.pointer << " -> " << error;
    }
  }
}

TEST(MetadataErrors, NeedsALidarModeOrColumnsPerFrame) {
  nlohmann::json doc = read_json(kDocExample);
  doc["config_params"].erase("lidar_mode");
  doc["lidar_data_format"].erase("columns_per_frame");
  EXPECT_NE(error_of(doc).find("/config_params/lidar_mode"), std::string::npos) << error_of(doc);
  doc["lidar_data_format"]["columns_per_frame"] = 1024;
  EXPECT_EQ(error_of(doc), "(no error)");
}

TEST(MetadataErrors, RejectsAnythingButAnObject) {
  EXPECT_EQ(error_of(nlohmann::json::array(), "x.json"), "x.json: /: must be a JSON object, got an array of 0");
}

TEST(MetadataErrors, LoadNamesAMissingOrBrokenFile) {
  try {
    load_metadata("/nonexistent/meta.json");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/meta.json"), std::string::npos);
  }
  const auto broken =
      std::filesystem::temp_directory_path() / ("lidartwin_broken_" + std::to_string(getpid()) + ".json");
  std::ofstream(broken) << "{\"sensor_info\": ";
  try {
    load_metadata(broken);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not valid JSON"), std::string::npos) << e.what();
  }
  std::filesystem::remove(broken);
}

TEST(DefaultConfigParams, IsTheFirmware31ConfigOfTheProtocolDoc) {
  EXPECT_EQ(default_config_params(), read_json(kDocExample)["config_params"]);
}

Metadata make_from_file(const std::filesystem::path& path) {
  const Metadata real = load_metadata(path);
  return make_metadata(real.sensor_info, real.beams, real.config_params);
}

TEST(MakeMetadata, ReproducesTheProtocolDocExample) {
  const nlohmann::json example = read_json(kDocExample);
  EXPECT_EQ(to_nested_json(make_from_file(kDocExample)), example);
}

TEST(MakeMetadata, DerivesTheFormatRealFirmware3SensorsReport) {
  // FW 3.x files: shifts are round(az * W / 360) (protocol doc 3.4), windows per doc 6.4, IMU counts.
  for (const char* file :
       {"shot_limiting_test.json", "crc_test.json", "metadata/3_0_1_os-122246000293-128.json",
        "OS-1-128_767798045_1024x10_20230712_120049.json", "same_ports_nonlegacy.1.json", "windowed_frame1_0.json",
        "windowed_frame2_0.json", "metadata/2_5_0_os-992146000760-128.json"}) {
    const Metadata real = load_metadata(kSamples / file);
    LidarDataFormat made = make_from_file(kSamples / file).format;
    if (std::string(file).starts_with("windowed") || std::string(file).starts_with("metadata/2_5")) {
      made.pixel_shift_by_row = real.format.pixel_shift_by_row;  // FW 2.x shifts use another convention
    }
    EXPECT_EQ(made, real.format) << file;
  }
}

TEST(MakeMetadata, RoundTripsThroughParse) {
  nlohmann::json config = {{"lidar_mode", "2048x10"},
                           {"udp_profile_imu", "ACCEL32_GYRO32_NMEA"},
                           {"azimuth_window", {300000, 100000}},
                           {"udp_profile_lidar", "FUSA_RNG15_RFL8_NIR8_DUAL"}};
  const Metadata made = make_metadata(load_metadata(kDocExample).sensor_info, load_metadata(kDocExample).beams, config);
  EXPECT_EQ(made.format.header_type, HeaderType::kFusa);
  EXPECT_EQ(made.format.imu_measurements_per_packet, 8);  // 640 Hz / (10 fps * 8 packets)
  EXPECT_EQ(parse_metadata(to_nested_json(made), "made"), made);
}

TEST(MakeMetadata, NamesTheBadConfigKey) {
  const Metadata base = load_metadata(kDocExample);
  try {
    make_metadata(base.sensor_info, base.beams, {{"lidar_mode", "640x10"}});
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("config_params: /lidar_mode: must be one of", 0), 0u) << e.what();
  }
  EXPECT_THROW(make_metadata(base.sensor_info, base.beams, {{"azimuth_window", {0, 400000}}}), InputError);
  EXPECT_THROW(make_metadata(base.sensor_info, base.beams, {{"columns_per_packet", "16"}}), InputError);
}

}  // namespace
}  // namespace lidartwin

namespace lidartwin {
namespace {
// lidar_frame_azimuth_offset (FW 3.2 POST config docs): 90000 rotates the lidar frame 90 deg
// counter-clockwise, so the first column (lidar +X) points at sensor azimuth 270 deg (-Y) instead of
// 180 deg (-X). The served lidar_to_sensor_transform carries it; zero changes nothing.
TEST(MakeMetadata, LidarFrameAzimuthOffsetRotatesTheServedLidarFrame) {
  const Metadata base = load_metadata(kDocExample);
  const Metadata unrotated = make_metadata(base.sensor_info, base.beams, {{"lidar_frame_azimuth_offset", 0}});
  EXPECT_EQ(unrotated.beams.lidar_to_sensor, base.beams.lidar_to_sensor);
  const Metadata rotated = make_metadata(base.sensor_info, base.beams, {{"lidar_frame_azimuth_offset", 90000}});
  const auto& T = rotated.beams.lidar_to_sensor;
  EXPECT_NEAR(T[0], 0.0, 1e-12);  // image of lidar +X: (T[0], T[4], T[8]) = sensor -Y
  EXPECT_NEAR(T[4], -1.0, 1e-12);
  EXPECT_NEAR(T[8], 0.0, 1e-12);
  EXPECT_EQ(T[11], base.beams.lidar_to_sensor[11]);  // translation unchanged
  EXPECT_EQ(parse_metadata(to_nested_json(rotated), "rotated").beams, rotated.beams);
}

}  // namespace
}  // namespace lidartwin
