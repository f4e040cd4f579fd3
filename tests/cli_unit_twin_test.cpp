// `record` and `fit` with `--profile UNIT.json`, a real unit's metadata file: the capture is one the
// unit's own metadata file decodes, the fitted profile is still that unit, and files that cannot
// make a twin are refused with messages naming the file and the key.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/profile/sensor_profile.h"
#include "support/cli_run.h"
#include "support/record_capture.h"

namespace lidartwin::cli_unit_twin_test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::run_cli;

const fs::path kSamples = fs::path(LIDARTWIN_TEST_DATA) / "ouster-samples";

// A path as one word of the shell command run_cli runs.
std::string arg(const fs::path& path) { return "'" + path.string() + "'"; }

// `record --profile UNIT.json` of the hall, 2 frames, in the unit's own format.
test::CliRun record_twin(const fs::path& unit, const fs::path& out, const std::string& extra = "") {
  return run_cli("record --profile " + arg(unit) + " --scene " + arg(test::hall_scene()) + " --pose '" +
                 test::kHallPose + "' --frames 2 --threads 1 --out " + arg(out) + " " + extra);
}

// The number after `label` on a line of pcap-info's output ("frames: 2"); -1 if absent.
long long count_after(const std::string& output, const std::string& label) {
  const size_t at = output.find("\n" + label);
  if (at == std::string::npos) return -1;
  return std::stoll(output.substr(at + 1 + label.size()));
}

class UnitTwinRecord : public ::testing::TestWithParam<std::string> {};

// A flat FW 2.2 OS-0-32 (dual returns), a nested FW 2.2 OS-1-128 (LEGACY packets), a nested
// FW 3.0 OS-0-128 (dual) and a FW 3.1 OS-1-128 in the FUSA profile.
INSTANTIATE_TEST_SUITE_P(Units, UnitTwinRecord,
                         ::testing::Values("OS-0-32-U1_v2.2.0_1024x10.json", "metadata/2_2_os-992119000444-128.json",
                                           "OS-0-128_v3.0.1_1024x10.json",
                                           "OS-1-128_767798045_1024x10_20230712_120049.json"));

TEST_P(UnitTwinRecord, CaptureDecodesWithTheUnitsOwnMetadataFile) {
  const fs::path unit = kSamples / GetParam();
  const fs::path out = fs::path(testing::TempDir()) / ("twin_record_" + fs::path(GetParam()).stem().string());
  fs::remove_all(out);
  const test::CliRun recorded = record_twin(unit, out);
  ASSERT_EQ(recorded.exit_code, 0) << recorded.output;

  // The unit's file, not the recorded one, reads the capture: same format, serial and session.
  const test::CliRun info = run_cli("pcap-info " + arg(out / "capture.pcap") + " --metadata " + arg(unit));
  ASSERT_EQ(info.exit_code, 0) << info.output;
  const Metadata own = load_metadata(unit);
  const long long expected_packets = 2LL * own.format.columns_per_frame / own.format.columns_per_packet;
  EXPECT_EQ(count_after(info.output, "lidar packets: "), expected_packets) << info.output;
  EXPECT_EQ(count_after(info.output, "frames: "), 2) << info.output;
  EXPECT_EQ(count_after(info.output, "valid columns per frame: "),
            own.format.column_window[1] - own.format.column_window[0] + 1)
      << info.output;
  EXPECT_EQ(info.output.find("other sensor or session"), std::string::npos) << info.output;
  EXPECT_EQ(info.output.find("malformed"), std::string::npos) << info.output;
  if (own.format.udp_profile_lidar != UdpProfileLidar::kLegacy) {
    EXPECT_EQ(count_after(info.output, "crc failures: "), 0) << info.output;
  }

  const Metadata written = load_metadata(out / "metadata.json");
  EXPECT_EQ(written.sensor_info.prod_sn, own.sensor_info.prod_sn);
  EXPECT_EQ(written.sensor_info.build_rev, own.sensor_info.build_rev);
  EXPECT_EQ(written.beams, own.beams);
}

// A flag still chooses: --mode over the unit's 1024x10, the unit's packet profile kept.
TEST(UnitTwinRecordFlags, ModeFlagOverridesTheUnitsMode) {
  const fs::path unit = kSamples / "OS-0-128_v3.0.1_1024x10.json";
  const fs::path out = fs::path(testing::TempDir()) / "twin_record_512";
  fs::remove_all(out);
  const test::CliRun recorded = record_twin(unit, out, "--mode 512x10");
  ASSERT_EQ(recorded.exit_code, 0) << recorded.output;
  const Metadata written = load_metadata(out / "metadata.json");
  EXPECT_EQ(written.format.columns_per_frame, 512);
  EXPECT_EQ(written.format.udp_profile_lidar, load_metadata(unit).format.udp_profile_lidar);
}

// `fit --profile UNIT.json` writes a profile that is still the unit: its product and every beam
// intrinsic, the family's chain (os1-32 for an OS-1-32-G) with the added effect, and it reads back.
TEST(UnitTwinFit, FittedProfileKeepsTheUnitsIntrinsics) {
  const fs::path unit = kSamples / "OS-1-32-G_v2.1.1_1024x10.json";
  const fs::path dir = fs::path(testing::TempDir()) / "twin_fit";
  fs::remove_all(dir);
  const test::CliRun recorded = record_twin(unit, dir / "capture");
  ASSERT_EQ(recorded.exit_code, 0) << recorded.output;
  const fs::path fitted = dir / "fitted.json";
  const test::CliRun fit = run_cli("fit --capture " + arg(dir / "capture") + " --scene " + arg(test::hall_scene()) +
                                   " --threads 1 --profile " + arg(unit) + " --add range_walk --out " + arg(fitted));
  ASSERT_EQ(fit.exit_code, 0) << fit.output;

  const SensorProfile profile = load_profile(fitted.string());
  const Metadata own = load_metadata(unit);
  EXPECT_EQ(profile.beams, own.beams);
  EXPECT_EQ(profile.prod_line, own.sensor_info.prod_line);
  EXPECT_EQ(profile.prod_pn, own.sensor_info.prod_pn);
  EXPECT_NE(profile.source.find(unit.string()), std::string::npos) << profile.source;
  // The family's chain with the fitted effect placed where the chain's order puts it.
  const SensorProfile family = load_profile("os1-32");
  std::vector<std::string> names;
  for (const auto& effect : profile.effects) {
    if (effect["name"] != "range_walk") names.push_back(effect["name"]);
  }
  std::vector<std::string> family_names;
  for (const auto& effect : family.effects) family_names.push_back(effect["name"]);
  EXPECT_EQ(names, family_names) << profile.effects.dump();
  EXPECT_EQ(profile.effects.size(), family.effects.size() + 1) << profile.effects.dump();
  EXPECT_EQ(profile.min_range_m, family.min_range_m);
  EXPECT_EQ(profile.max_range_m, family.max_range_m);
}

// ---- files that make no twin ----

fs::path write_file(const std::string& name, const std::string& text) {
  const fs::path path = fs::path(testing::TempDir()) / name;
  std::ofstream(path) << text;
  return path;
}

json sample(const std::string& name) {
  std::ifstream in(kSamples / name);
  return json::parse(in);
}

void expect_refused(const fs::path& file, const std::vector<std::string>& named) {
  const test::CliRun run = record_twin(file, fs::path(testing::TempDir()) / "twin_refused");
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find(file.string()), std::string::npos) << run.output;
  for (const std::string& text : named)
    EXPECT_NE(run.output.find(text), std::string::npos) << text << "\n" << run.output;
}

TEST(UnitTwinInput, RefusesAProductLineWithoutAShippedProfile) {
  json unit = sample("OS-0-128_v3.0.1_1024x10.json");
  unit["sensor_info"]["prod_line"] = "OS-DOME-128";
  expect_refused(write_file("dome.json", unit.dump()),
                 {"/sensor_info/prod_line", "\"OS-DOME-128\" has no shipped profile", "os0-128"});
  json flat = sample("OS-1-128_v2.3.0_1024x10.json");
  flat["prod_line"] = "OS-1-256";
  expect_refused(write_file("os1_256.json", flat.dump()), {"/prod_line", "no os1-256.json"});
}

TEST(UnitTwinInput, RefusesATruncatedFile) {
  std::ifstream in(kSamples / "OS-0-128_v3.0.1_1024x10.json");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  expect_refused(write_file("truncated.json", text.substr(0, text.size() / 2)), {"not valid JSON"});
}

TEST(UnitTwinInput, RefusesMissingBeamIntrinsics) {
  json unit = sample("OS-0-128_v3.0.1_1024x10.json");
  unit["beam_intrinsics"].erase("beam_azimuth_angles");
  expect_refused(write_file("no_azimuths.json", unit.dump()), {"/beam_intrinsics/beam_azimuth_angles"});
}

TEST(UnitTwinInput, RefusesAFileWithoutAProductLine) {
  json flat = sample("OS-2-32-U0_v2.0.0_1024x10.json");
  flat.erase("prod_line");
  expect_refused(write_file("no_prod_line.json", flat.dump()), {"/prod_line: missing"});
}

}  // namespace
}  // namespace lidartwin::cli_unit_twin_test
