// Profiles: every shipped profile loads; real-metadata profiles carry the sample calibration
// unchanged (read here independently of the loader); the noise tables match the paper's Table I;
// bad files fail with messages that name the file, the JSON pointer and the allowed range.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>

#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/error.h"
#include "lidartwin/profile/product_line.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

const fs::path kSamples = fs::path(LIDARTWIN_TEST_DATA) / "ouster-samples";

json read_json(const fs::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  return json::parse(in);
}

// A sample's intrinsics, in either metadata layout (nested FW 2.x/3.x or flat; protocol doc 3.2).
json sample_section(const json& metadata, const char* nested, const char* key) {
  return metadata.contains(nested) ? metadata.at(nested).at(key) : metadata.at(key);
}

TEST(Profile, EveryShippedProfileLoads) {
  const std::vector<std::string> expected{"os0-128",      "os0-32", "os0-32-paper", "os0-64", "os1-128", "os1-32",
                                          "os1-32-paper", "os1-64", "os2-128",      "os2-32", "os2-64"};
  EXPECT_EQ(available_profiles(), expected);
  for (const auto& name : expected) {
    const SensorProfile profile = load_profile(name);
    EXPECT_EQ(profile.name, name);
    EXPECT_FALSE(profile.source.empty()) << name;
    EXPECT_FALSE(profile.effects.empty()) << name;
  }
}

TEST(Profile, BeamCountsAndProductLines) {
  const std::map<std::string, std::pair<int, std::string>> expected{
      {"os0-32", {32, "OS-0-32-U1"}},    {"os0-64", {64, "OS-0-64"}},      {"os0-128", {128, "OS-0-128"}},
      {"os1-32", {32, "OS-1-32-G"}},     {"os1-64", {64, "OS-1-64"}},      {"os1-128", {128, "OS-1-128"}},
      {"os2-32", {32, "OS-2-32-U0"}},    {"os2-64", {64, "OS-2-64"}},      {"os2-128", {128, "OS-2-128"}},
      {"os0-32-paper", {32, "OS-0-32"}}, {"os1-32-paper", {32, "OS-1-32"}}};
  for (const auto& [name, count_and_line] : expected) {
    const SensorProfile profile = load_profile(name);
    EXPECT_EQ(profile.beams.pixels_per_column(), count_and_line.first) << name;
    EXPECT_EQ(profile.beams.azimuth_deg.size(), profile.beams.altitude_deg.size()) << name;
    EXPECT_EQ(profile.prod_line, count_and_line.second) << name;
  }
}

// profile name → (sample file, first row, row step): the 64-beam profiles take every other row.
struct SampleSource {
  const char* file;
  size_t first_row;
  size_t row_step;
};

TEST(Profile, RealMetadataProfilesEqualTheirSample) {
  const std::map<std::string, SampleSource> sources{{"os0-32", {"OS-0-32-U1_v2.2.0_1024x10.json", 0, 1}},
                                                    {"os0-64", {"OS-0-128-U1_v2.3.0_1024x10.json", 0, 2}},
                                                    {"os0-128", {"OS-0-128-U1_v2.3.0_1024x10.json", 0, 1}},
                                                    {"os1-32", {"OS-1-32-G_v2.1.1_1024x10.json", 0, 1}},
                                                    {"os1-64", {"metadata/2_1_2_os1-991913000010-64.json", 0, 1}},
                                                    {"os1-128", {"OS-1-128_v2.3.0_1024x10.json", 0, 1}},
                                                    {"os2-32", {"OS-2-32-U0_v2.0.0_1024x10.json", 0, 1}},
                                                    {"os2-64", {"OS-2-128-U1_v2.3.0_1024x10.json", 0, 2}},
                                                    {"os2-128", {"OS-2-128-U1_v2.3.0_1024x10.json", 0, 1}}};
  for (const auto& [name, source] : sources) {
    SCOPED_TRACE(name);
    const SensorProfile profile = load_profile(name);
    const json metadata = read_json(kSamples / source.file);
    const auto altitude =
        sample_section(metadata, "beam_intrinsics", "beam_altitude_angles").get<std::vector<double>>();
    const auto azimuth = sample_section(metadata, "beam_intrinsics", "beam_azimuth_angles").get<std::vector<double>>();
    ASSERT_EQ(profile.beams.altitude_deg.size() * source.row_step, altitude.size());
    for (size_t row = 0; row < profile.beams.altitude_deg.size(); ++row) {
      EXPECT_EQ(profile.beams.altitude_deg[row], altitude[source.first_row + row * source.row_step]) << row;
      EXPECT_EQ(profile.beams.azimuth_deg[row], azimuth[source.first_row + row * source.row_step]) << row;
    }
    const double origin = sample_section(metadata, "beam_intrinsics", "lidar_origin_to_beam_origin_mm").get<double>();
    EXPECT_EQ(profile.beams.lidar_origin_to_beam_origin_mm, origin);
    EXPECT_EQ(profile.beams.beam_to_lidar[3], origin);  // SDK default when the sample has no matrix
    EXPECT_EQ(profile.beams.lidar_to_sensor,
              (sample_section(metadata, "lidar_intrinsics", "lidar_to_sensor_transform").get<Mat4>()));
    EXPECT_EQ(profile.beams.imu_to_sensor,
              (sample_section(metadata, "imu_intrinsics", "imu_to_sensor_transform").get<Mat4>()));
    EXPECT_THAT(profile.source, HasSubstr(fs::path(source.file).filename().string()));
  }
}

TEST(Profile, PaperProfilesReproduceSectionIII) {
  struct Expected {
    const char* name;
    double half_fov_deg, max_range_m, sigma_max_m;
  };
  for (const Expected& e : {Expected{"os0-32-paper", 45.0, 45.0, 0.10}, Expected{"os1-32-paper", 22.5, 100.0, 0.15}}) {
    SCOPED_TRACE(e.name);
    const SensorProfile profile = load_profile(e.name);
    ASSERT_EQ(profile.beams.pixels_per_column(), 32);
    for (int row = 0; row < 32; ++row) {
      EXPECT_NEAR(profile.beams.altitude_deg[static_cast<size_t>(row)], e.half_fov_deg - row * 2 * e.half_fov_deg / 31,
                  1e-6);
      EXPECT_EQ(profile.beams.azimuth_deg[static_cast<size_t>(row)], 0.0);
    }
    EXPECT_EQ(profile.max_range_m, e.max_range_m);
    EXPECT_EQ(profile.lidar_modes, (std::vector<std::string>{"512x10", "512x20"}));
    const json noise = profile.effects.at(1);
    EXPECT_EQ(noise, (json{{"name", "range_noise_linear"},
                           {"sigma0_m", 0.01},
                           {"sigma_max_m", e.sigma_max_m},
                           {"range_max_m", e.max_range_m}}));
  }
}

// Linear interpolation through the knots, written here independently of effects/.
double piecewise_sigma(const json& points, double range_m) {
  for (size_t i = 1; i < points.size(); ++i) {
    const double r0 = points[i - 1][0], s0 = points[i - 1][1], r1 = points[i][0], s1 = points[i][1];
    if (range_m <= r1) return s0 + (s1 - s0) * (range_m - r0) / (r1 - r0);
  }
  return points.back()[1];
}

TEST(Profile, PiecewiseNoiseMatchesTableIInsideEveryInterval) {
  // Paper Table I (10 % Lambertian); {lower m, upper m, sigma m}.
  const std::vector<std::array<double, 3>> os0{{0.3, 1, 0.02}, {1, 10, 0.01}, {10, 15, 0.015}, {15, 45, 0.05}};
  const std::vector<std::array<double, 3>> os1{{0.3, 1, 0.007}, {1, 20, 0.01}, {20, 50, 0.02}, {50, 100, 0.05}};
  for (const auto& [family, table] : {std::pair{"os0", os0}, std::pair{"os1", os1}}) {
    for (const char* beams : {"-32", "-64", "-128"}) {
      const SensorProfile profile = load_profile(std::string(family) + beams);
      SCOPED_TRACE(profile.name);
      const auto found = std::find_if(profile.effects.begin(), profile.effects.end(),
                                      [](const json& e) { return e.at("name") == "range_noise_piecewise"; });
      ASSERT_NE(found, profile.effects.end());
      const json& noise = *found;
      for (const auto& [lower, upper, sigma] : table) {
        // Knots sit 2 % inside each edge, so the curve equals the table away from the edges.
        for (double u = 0.0; u <= 1.0; u += 0.125) {
          const double r = lower * 1.02 + u * (upper * 0.98 - lower * 1.02);
          EXPECT_NEAR(piecewise_sigma(noise.at("points_m"), r), sigma, 1e-12) << r;
        }
      }
    }
  }
}

TEST(Profile, RangeLimitsEffectAgreesWithTheProfile) {
  for (const auto& name : available_profiles()) {
    const SensorProfile profile = load_profile(name);
    std::vector<std::string> names;
    for (const json& effect : profile.effects) names.push_back(effect.at("name"));
    ASSERT_GE(names.size(), 4u) << name;
    EXPECT_EQ(names.front(), "radiometry");
    EXPECT_EQ(names.back(), "range_quantization");
    const size_t limits = names.size() - 2;
    EXPECT_EQ(names[limits], "range_limits");
    EXPECT_EQ(profile.effects[limits].at("min_m"), profile.min_range_m) << name;
    EXPECT_EQ(profile.effects[limits].at("max_m"), profile.max_range_m) << name;
  }
}

// The datasheet profiles enable the effects with a sourced default (lidar-physics.md): incidence
// with the datasheet's beam divergence (E4, [S1]) unless a fit on a real capture changed it; on
// OS1, detection from the signal, whose default threshold is set from the OS1 range specification
// (E5, [S1]); and what real captures support: E2 and its tails fitted, E6 (DUAL second returns); on OS2, whose
// only real capture is one frame of an OS-2-128, incidence and E2's tails fitted there (and no E2
// k, which added nothing after them), and E6 with the footprint incidence found. Every effect whose parameters are not
// the library's defaults says where they came from. The paper profiles stay the paper's law; the detection threshold of
// OS0 and OS2 has no source.
TEST(Profile, DatasheetProfilesEnableTheEffectsWithSourcedDefaults) {
  for (const auto& name : available_profiles()) {
    const SensorProfile profile = load_profile(name);
    std::vector<std::string> names;
    for (const json& effect : profile.effects) names.push_back(effect.at("name"));
    const auto has = [&](const char* effect) { return std::find(names.begin(), names.end(), effect) != names.end(); };
    const bool paper = name.ends_with("-paper"), os0 = name.starts_with("os0"), os1 = name.starts_with("os1");
    const bool os2 = name.starts_with("os2");
    EXPECT_EQ(has("incidence"), !paper) << name;
    EXPECT_EQ(has("dropout"), !paper && os1) << name;
    EXPECT_EQ(has("signal_precision"), !paper && (os0 || os1)) << name;
    EXPECT_EQ(has("signal_outliers"), !paper) << name;
    EXPECT_EQ(has("mixed_pixels"), !paper) << name;
    for (const json& effect : profile.effects) {
      const std::string source = effect.value("source", "");
      if (effect.at("name") == "incidence" && source.find("lidartwin fit") == std::string::npos) {
        EXPECT_EQ(effect.at("divergence_rad"), profile.beam_divergence_rad) << name;
      }
      if (effect.at("name") == "signal_precision") {
        EXPECT_GT(effect.at("k_m").get<double>(), 0.0) << name;
        EXPECT_NE(source.find("lidartwin fit"), std::string::npos) << name << ": " << source;
      }
      // OS2's table is a placeholder (README, "Range noise"); the rest was fitted on its sample.
      if (os2 && effect.size() > 1 && effect.at("name") != "range_limits" &&
          effect.at("name") != "range_noise_piecewise") {
        EXPECT_NE(source.find("OS-2-128-U1_v2.3.0_1024x10.pcap"), std::string::npos) << name << ": " << source;
      }
      if (!paper && (os0 || os1) && effect.size() > 1 && effect.at("name") != "range_limits") {
        EXPECT_FALSE(source.empty()) << name << ": " << effect.dump();
      }
    }
  }
}

class BadProfile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lidartwin_profile_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    good_ = read_json(profiles_dir() / "os1-64.json");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes `document` as bad.json and returns the loader's message.
  std::string error_for(const json& document) { return error_for_text(document.dump(2)); }
  std::string error_for_text(const std::string& text) {
    std::ofstream(dir_ / "bad.json") << text;
    try {
      load_profile((dir_ / "bad.json").string());
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no InputError for " << text.substr(0, 200);
    return {};
  }
  std::string path() const { return (dir_ / "bad.json").string(); }

  fs::path dir_;
  json good_;
};

TEST_F(BadProfile, BaseDocumentIsValid) {
  std::ofstream(dir_ / "good.json") << good_.dump();
  EXPECT_EQ(load_profile((dir_ / "good.json").string()).name, "good");
}

TEST_F(BadProfile, OutOfRangeNamesFilePointerAndAllowedRange) {
  good_["max_range_m"] = -3;
  EXPECT_EQ(error_for(good_), path() + ": /max_range_m: must be in (0, 1000], got -3");
}

TEST_F(BadProfile, AltitudeOutsideNinetyDegrees) {
  good_["beam_intrinsics"]["beam_altitude_angles"][5] = 95.5;
  EXPECT_EQ(error_for(good_), path() + ": /beam_intrinsics/beam_altitude_angles/5: must be in [-90, 90], got 95.5");
}

TEST_F(BadProfile, UnknownKeyListsTheAllowedOnes) {
  good_["max_rnage_m"] = 100;
  const std::string message = error_for(good_);
  EXPECT_THAT(message, HasSubstr(path() + ": /max_rnage_m: unknown key; allowed keys here: prod_line"));
  EXPECT_THAT(message, HasSubstr("max_range_m"));
}

// How far units differ, as the OS0 and OS2 profiles say it: a factor of at least 1, with its source.
TEST_F(BadProfile, UnitToUnitSpreadIsAFactorWithItsSource) {
  good_["unit_to_unit"] = {{"range_spread", 2.0}, {"source", "two units"}};
  std::ofstream(dir_ / "good.json") << good_.dump();
  const SensorProfile profile = load_profile((dir_ / "good.json").string());
  EXPECT_EQ(profile.unit_range_spread, 2.0);
  EXPECT_EQ(profile.unit_to_unit_source, "two units");
  good_["unit_to_unit"]["range_spread"] = 0.5;
  EXPECT_EQ(error_for(good_), path() + ": /unit_to_unit/range_spread: must be in [1, 10], got 0.5");
  good_["unit_to_unit"].erase("source");
  good_["unit_to_unit"]["range_spread"] = 2.0;
  EXPECT_EQ(error_for(good_), path() + ": /unit_to_unit/source: missing (expected a string)");
  EXPECT_EQ(load_profile("os0-128").unit_range_spread, 2.0);
  EXPECT_EQ(load_profile("os1-128").unit_range_spread, 0.0) << "not known for the OS1 line";
}

TEST_F(BadProfile, SensorMetadataIsNamedAsSuch) {
  const json metadata = {{"sensor_info", {{"base_pn", "000-101323-03"}}}, {"lidar_data_format", json::object()}};
  EXPECT_THAT(error_for(metadata), HasSubstr(path() + ": this is a sensor's metadata, not a profile"));
}

TEST_F(BadProfile, UnknownKeyInsideBeamIntrinsics) {
  good_["beam_intrinsics"]["altitudes"] = json::array();
  EXPECT_THAT(error_for(good_), HasSubstr(": /beam_intrinsics/altitudes: unknown key"));
}

TEST_F(BadProfile, MissingKey) {
  good_.erase("min_range_m");
  EXPECT_EQ(error_for(good_), path() + ": /min_range_m: missing (expected a number in [0, 1000))");
}

TEST_F(BadProfile, WrongType) {
  good_["beam_divergence_rad"] = "0.002";
  EXPECT_EQ(error_for(good_), path() + ": /beam_divergence_rad: must be a number in (0, 0.1], got a string \"0.002\"");
  good_ = read_json(profiles_dir() / "os1-64.json");
  good_["prod_line"] = 64;
  EXPECT_EQ(error_for(good_), path() + ": /prod_line: must be a string, got a number 64");
}

TEST_F(BadProfile, ArraysOfDifferentLengths) {
  good_["beam_intrinsics"]["beam_azimuth_angles"].erase(0);
  EXPECT_EQ(error_for(good_), path() +
                                  ": /beam_intrinsics/beam_azimuth_angles: must have as many entries as "
                                  "beam_altitude_angles (64), got 63");
}

TEST_F(BadProfile, BeamCountDisagreesWithProductLine) {
  good_["prod_line"] = "OS-1-128";
  EXPECT_EQ(error_for(good_), path() + ": /prod_line: names 128 beams but beam_intrinsics has 64");
  for (const char* bad : {"OS-1", "OS-3-64", "VLP-16", "OS-1-64-", "OS-1-64 U"}) {
    good_["prod_line"] = bad;
    EXPECT_THAT(error_for(good_), HasSubstr(": /prod_line: must look like \"OS-1-64\" or \"OS-0-32-U1\"")) << bad;
  }
  good_["prod_line"] = "OS-1-64-AH";
  std::ofstream(dir_ / "variant.json") << good_.dump();
  EXPECT_EQ(load_profile((dir_ / "variant.json").string()).prod_line, "OS-1-64-AH");
}

TEST_F(BadProfile, MinRangeNotBelowMaxRange) {
  good_["min_range_m"] = 100.0;
  EXPECT_THAT(error_for(good_), HasSubstr(path() + ": /min_range_m: must be below max_range_m"));
}

TEST_F(BadProfile, TransformsAndModes) {
  good_["beam_intrinsics"]["lidar_to_sensor_transform"] = json::array({1, 0, 0});
  EXPECT_THAT(error_for(good_), HasSubstr("/beam_intrinsics/lidar_to_sensor_transform: must have 16 numbers"));
  good_ = read_json(profiles_dir() / "os1-64.json");
  good_["beam_intrinsics"]["beam_to_lidar_transform"][3] = 1.0;
  EXPECT_THAT(error_for(good_), HasSubstr("/beam_intrinsics/beam_to_lidar_transform: entry [0][3] must equal"));
  good_ = read_json(profiles_dir() / "os1-64.json");
  good_["lidar_modes"][1] = "2048x20";
  EXPECT_THAT(error_for(good_), HasSubstr("/lidar_modes/1: must be one of 512x10"));
}

TEST_F(BadProfile, EffectsMustBeNamedObjects) {
  good_["effects"][2] = json{{"min_m", 0.3}};
  EXPECT_EQ(error_for(good_), path() + ": /effects/2: must be an object with a string \"name\"");
  good_["effects"] = json::object();
  EXPECT_EQ(error_for(good_), path() + ": /effects: must be an array of effect objects, got an object");
}

TEST_F(BadProfile, NotJsonAndMissingFiles) {
  EXPECT_THAT(error_for_text("{\"prod_line\": "), HasSubstr(path() + ": not valid JSON: "));
  EXPECT_THAT(error_for_text("[1, 2]"), HasSubstr(path() + ": /: must be an object, got an array"));
  try {
    load_profile("os9-99");
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("profile \"os9-99\": no "));
    EXPECT_THAT(e.what(), HasSubstr("available: os0-128, os0-32"));
  }
}

TEST_F(BadProfile, EnvironmentOverridesTheProfilesDirectory) {
  std::ofstream(dir_ / "mine.json") << good_.dump();
  ::setenv("LIDARTWIN_PROFILES", dir_.c_str(), 1);
  EXPECT_EQ(available_profiles(), (std::vector<std::string>{"mine"}));
  EXPECT_EQ(load_profile("mine").prod_line, "OS-1-64");
  ::unsetenv("LIDARTWIN_PROFILES");
  EXPECT_EQ(profiles_dir(), fs::path(LIDARTWIN_SOURCE_DIR) / "profiles");
}

}  // namespace
}  // namespace lidartwin

namespace lidartwin {
namespace {

// The product-line rules profiles and metadata share (protocol doc 3.1).
TEST(ProductLine, BeamsFamilyAndShape) {
  EXPECT_EQ(beam_count_of("OS-1-64"), 64);
  EXPECT_EQ(beam_count_of("OS-0-32-U1"), 32);
  EXPECT_EQ(beam_count_of("OS-DOME-128"), 128);
  EXPECT_EQ(beam_count_of("OS1"), std::nullopt);
  EXPECT_DOUBLE_EQ(default_lidar_origin_to_beam_origin_mm("OS-0-128"), 27.67);
  EXPECT_DOUBLE_EQ(default_lidar_origin_to_beam_origin_mm("OS-2-32-U0"), 13.762);
  EXPECT_DOUBLE_EQ(default_lidar_origin_to_beam_origin_mm("OS-01-64"), 12.163);  // not the OS-0 family
  EXPECT_TRUE(is_current_product_line("OS-0-32-U1"));
  EXPECT_FALSE(is_current_product_line("OS-3-64"));
  EXPECT_FALSE(is_current_product_line("OS-1-64-"));
  EXPECT_FALSE(is_current_product_line("OS-1-12345"));
}

}  // namespace
}  // namespace lidartwin
