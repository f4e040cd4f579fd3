// OSF recordings (ouster-cli's `save x.osf`) given to `lidartwin compare` and `pcap-info` as a user
// gives them: without --metadata, since the file carries it. Judged against the same capture as a
// pcap (ouster-sdk's tests ship the lb_n3 OS-1-128 capture both ways), and against broken files.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"
#include "support/table_profile.h"

namespace cli_osf_test {

namespace fs = std::filesystem;

namespace {

using lidartwin::test::CliRun;
using lidartwin::test::run_cli;

const std::string kSamples = std::string(LIDARTWIN_TEST_DATA) + "/ouster-samples/";
const std::string kPcap = kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap";
const std::string kJson = kSamples + "OS-1-128_v2.3.0_1024x10.json";
const std::string kOsf = kSamples + "osfs/OS-1-128_v2.3.0_1024x10_lb_n3.osf";

fs::path temp(const std::string& name) {
  const fs::path dir = fs::path(testing::TempDir()) / ("osf_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::vector<uint8_t> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

std::string line_starting(const std::string& output, const std::string& start) {
  const size_t at = output.find(start);
  return at == std::string::npos ? std::string() : output.substr(at, output.find('\n', at) - at);
}

// CRC-32 (IEEE, reflected), bit by bit: what OSF blocks end with.
uint32_t crc32(const uint8_t* data, size_t size) {
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < size; ++i) {
    crc ^= data[i];
    for (int k = 0; k < 8; ++k) crc = (crc & 1u) ? (crc >> 1) ^ 0xEDB88320u : crc >> 1;
  }
  return ~crc;
}

TEST(CliOsf, PcapInfoSummarizesTheRecordingAsThePcapOfTheSameCapture) {
  const CliRun osf = run_cli("pcap-info " + kOsf);
  ASSERT_EQ(osf.exit_code, 0) << osf.output;
  EXPECT_NE(osf.output.find("(OSF 2.1, written by ouster_sdk)"), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("ouster/v1/os_sensor/LidarScanStream"), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("lidar streams: 1 "), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("metadata: (stored in the OSF file)"), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("sensor: OS-1-128, sn 122201000998"), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("mode: 1024x10, 128 beams"), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("profile: RNG15_RFL8_NIR8"), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("scans: 3\n"), std::string::npos) << osf.output;
  EXPECT_NE(osf.output.find("valid columns per scan: 1024\n"), std::string::npos) << osf.output;
  // Three frames at 10 Hz: from the first column to the last, a little under 0.3 s.
  EXPECT_NE(osf.output.find("time span: 0.29"), std::string::npos) << osf.output;

  const CliRun pcap = run_cli("pcap-info " + kPcap + " --metadata " + kJson);
  ASSERT_EQ(pcap.exit_code, 0) << pcap.output;
  const std::string fraction = line_starting(pcap.output, "valid pixel fraction: ");
  ASSERT_FALSE(fraction.empty()) << pcap.output;
  EXPECT_EQ(line_starting(osf.output, "valid pixel fraction: "), fraction);
}

// Map mode is where a pixel's place matters (its point, its neighbours in the other frames): the
// OSF, read without --metadata, must give the report the pcap gives.
TEST(CliOsf, CompareMapReportsTheSameFiguresForThePcapAndTheOsf) {
  const fs::path dir = temp("compare_map");
  const std::string common = " --map --profile os1-128 --no-plots --threads 2";
  const CliRun pcap =
      run_cli("compare --capture " + kPcap + " --metadata " + kJson + common + " --out " + (dir / "pcap").string());
  ASSERT_EQ(pcap.exit_code, 0) << pcap.output;
  const CliRun osf = run_cli("compare --capture " + kOsf + common + " --out " + (dir / "osf").string());
  ASSERT_EQ(osf.exit_code, 0) << osf.output;
  const nlohmann::json a = read_json(dir / "pcap" / "report.json");
  const nlohmann::json b = read_json(dir / "osf" / "report.json");
  EXPECT_GT(a["inputs"]["map"]["compared"].get<size_t>(), 100000u);
  EXPECT_EQ(b["inputs"]["map"], a["inputs"]["map"]);
  EXPECT_EQ(b["inputs"]["registration"], a["inputs"]["registration"]);
  EXPECT_EQ(b["inputs"]["frames"], a["inputs"]["frames"]);
  ASSERT_FALSE(a["bins"].empty());
  EXPECT_EQ(b["bins"], a["bins"]);
  EXPECT_EQ(b["failing"], a["failing"]);
  EXPECT_EQ(b["inputs"]["metadata"], "(stored in the OSF capture)");
  fs::remove_all(dir);
}

// fit reads the OSF as compare does: the profile it writes from the OSF is the pcap's, but for the
// capture it names.
TEST(CliOsf, FitWritesTheProfileThePcapGives) {
  const fs::path dir = temp("fit");
  const std::string common = " --map --profile " + table_profiles::datasheet_only_profile("os1-128").string() +
                             " --add signal_precision --threads 2";
  const CliRun pcap =
      run_cli("fit --capture " + kPcap + " --metadata " + kJson + common + " --out " + (dir / "pcap.json").string());
  ASSERT_EQ(pcap.exit_code, 0) << pcap.output;
  const CliRun osf = run_cli("fit --capture " + kOsf + common + " --out " + (dir / "osf.json").string());
  ASSERT_EQ(osf.exit_code, 0) << osf.output;
  nlohmann::json a = read_json(dir / "pcap.json"), b = read_json(dir / "osf.json");
  EXPECT_EQ(a["fit"]["capture"], kPcap);
  EXPECT_EQ(b["fit"]["capture"], kOsf);
  a["fit"].erase("capture");
  b["fit"].erase("capture");
  for (nlohmann::json* profile : {&a, &b}) {  // each fitted effect's source names the capture too
    for (auto& effect : (*profile)["effects"]) effect.erase("source");
  }
  ASSERT_TRUE(a["effects"].dump().find("signal_precision") != std::string::npos) << a["effects"].dump();
  EXPECT_EQ(b, a);
  fs::remove_all(dir);
}

TEST(CliOsf, AMetadataFileBesideTheOsfIsUsedAndSaidSo) {
  const fs::path dir = temp("override");
  // --map: the recording moves (0.75 m), which --static refuses.
  const CliRun r = run_cli("compare --map --frames 2 --capture " + kOsf + " --metadata " + kJson +
                           " --profile os1-128 --no-plots --out " + dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("note: --metadata " + kJson + " replaces the sensor metadata stored in the OSF file"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(read_json(dir / "report.json")["inputs"]["metadata"], kJson);
  fs::remove_all(dir);
}

TEST(CliOsf, ATruncatedRecordingIsRefusedByName) {
  const fs::path dir = temp("truncated");
  std::vector<uint8_t> bytes = read_bytes(kOsf);
  ASSERT_GT(bytes.size(), 600000u);
  bytes.resize(600000);  // as a copy interrupted mid-way: the metadata at the end is gone
  const fs::path cut = dir / "cut.osf";
  write_bytes(cut, bytes);
  for (const std::string& command :
       {"pcap-info " + cut.string(),
        "compare --map --profile os1-128 --capture " + cut.string() + " --out " + (dir / "out").string()}) {
    const CliRun r = run_cli(command);
    EXPECT_NE(r.exit_code, 0) << command;
    EXPECT_NE(r.output.find(cut.string() + ": truncated: its header says 1025780 bytes, the file has 600000"),
              std::string::npos)
        << r.output;
  }
  fs::remove_all(dir);
}

TEST(CliOsf, AFileNamedOsfWithoutAnOsfHeaderIsRefused) {
  const fs::path dir = temp("not_osf");
  const fs::path fake = dir / "metadata.osf";
  fs::copy_file(kJson, fake);
  const CliRun r =
      run_cli("compare --map --profile os1-128 --capture " + fake.string() + " --out " + (dir / "out").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find(fake.string() + ": not an OSF file (it does not start with an OSF header"), std::string::npos)
      << r.output;
  fs::remove_all(dir);
}

// An OSF file under another name is still read as one: by its header.
TEST(CliOsf, AnOsfFileIsToldByItsHeaderWhateverItsName) {
  const fs::path dir = temp("renamed");
  const fs::path renamed = dir / "recording.bin";
  fs::copy_file(kOsf, renamed);
  const CliRun r = run_cli("pcap-info " + renamed.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("scans: 3\n"), std::string::npos) << r.output;
  fs::remove_all(dir);
}

// ouster-cli 1.0 saves fields as ZPNG by default; single_scan_016.osf is such a file (an OS-0-128
// scan with the dual-return profile's nine fields).
TEST(CliOsf, ZpngFieldsAreRead) {
  const CliRun r = run_cli("pcap-info " + kSamples + "osfs/single_scan_016.osf");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("scans: 1\n"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("profile: RNG19_RFL8_SIG16_NIR16_DUAL"), std::string::npos) << r.output;
  const std::string fraction = line_starting(r.output, "valid pixel fraction: ");
  ASSERT_GT(fraction.size(), 28u) << r.output;
  EXPECT_GT(std::stod(fraction.substr(22)), 0.1) << "a scan with returns: " << fraction;
}

// The first field image in the lb_n3 recording's bytes with its PNG signature spoilt (and the
// chunk's CRC made right again, so the encoding is what is refused). Flatbuffers are built back to
// front: that image is the last scan's last field, NEAR_IR of scan 2.
TEST(CliOsf, AFieldEncodingNeitherPngNorZpngIsNamed) {
  const fs::path dir = temp("encoding");
  std::vector<uint8_t> bytes = read_bytes(kOsf);
  const uint8_t png[] = {0x89, 'P', 'N', 'G'};
  const auto at = std::search(bytes.begin(), bytes.end(), std::begin(png), std::end(png));
  ASSERT_NE(at, bytes.end());
  at[1] = 'X';
  // The first chunk block follows the header block: [u32 size][size bytes][u32 CRC-32 of both].
  const auto u32_at = [&](size_t i) {
    return bytes[i] | (size_t{bytes[i + 1]} << 8) | (size_t{bytes[i + 2]} << 16) | (size_t{bytes[i + 3]} << 24);
  };
  const size_t chunk = 4 + u32_at(0) + 4;
  const size_t size = u32_at(chunk);
  ASSERT_LT(static_cast<size_t>(at - bytes.begin()), chunk + 4 + size) << "the image lies in the first chunk";
  const uint32_t crc = crc32(bytes.data() + chunk, 4 + size);
  for (int k = 0; k < 4; ++k) bytes[chunk + 4 + size + static_cast<size_t>(k)] = static_cast<uint8_t>(crc >> (8 * k));
  const fs::path spoilt = dir / "spoilt.osf";
  write_bytes(spoilt, bytes);
  const CliRun r = run_cli("pcap-info " + spoilt.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find(spoilt.string() + ": scan 2, field NEAR_IR: encoded neither as PNG nor as ZPNG"),
            std::string::npos)
      << r.output;
  fs::remove_all(dir);
}

// The header's version, a flatbuffer field at byte 32 of this file: 21 (OSF 2.1). Major version 3
// could change the layout, so it is refused rather than misread.
TEST(CliOsf, AnUnsupportedVersionIsRefused) {
  const fs::path dir = temp("version");
  std::vector<uint8_t> bytes = read_bytes(kOsf);
  ASSERT_EQ(bytes[32], 21);
  const uint64_t version_3 = uint64_t{3} << 48;
  for (int k = 0; k < 8; ++k) bytes[32 + static_cast<size_t>(k)] = static_cast<uint8_t>(version_3 >> (8 * k));
  // The header block: [u32 size][size bytes][u32 CRC-32 of both].
  const size_t size = bytes[0] | (size_t{bytes[1]} << 8) | (size_t{bytes[2]} << 16) | (size_t{bytes[3]} << 24);
  const uint32_t crc = crc32(bytes.data(), 4 + size);
  for (int k = 0; k < 4; ++k) bytes[4 + size + static_cast<size_t>(k)] = static_cast<uint8_t>(crc >> (8 * k));
  const fs::path newer = dir / "newer.osf";
  write_bytes(newer, bytes);
  const CliRun r = run_cli("pcap-info " + newer.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find(newer.string() + ": OSF version 3.0 is not supported"), std::string::npos) << r.output;
  fs::remove_all(dir);
}

TEST(CliOsf, APcapStillNeedsItsMetadata) {
  const CliRun r = run_cli("compare --map --profile os1-128 --capture " + kPcap + " --out " +
                           (fs::path(testing::TempDir()) / "osf_pcap_no_metadata").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("give --metadata"), std::string::npos) << r.output;
}

}  // namespace

}  // namespace cli_osf_test
