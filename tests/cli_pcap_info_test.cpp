// `lidartwin pcap-info` on real captures: the printed counts match the sample README table.
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "support/cli_run.h"

namespace cli_pcap_info_test {

namespace {

using lidartwin::test::CliRun;
using lidartwin::test::run_cli;

const std::string kSamples = std::string(LIDARTWIN_TEST_DATA) + "/ouster-samples/";

bool has_line(const std::string& output, const std::string& line) {
  return output.find(line + "\n") != std::string::npos;
}

TEST(CliPcapInfo, CountsDatagramsByPortAndSize) {
  // README: 192 x 8448 B (3 frames) + 30 x 48 B.
  const CliRun run = run_cli("pcap-info " + kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(has_line(run.output, "  port  7502    8448 bytes  x 192")) << run.output;
  EXPECT_TRUE(has_line(run.output, "  port  7503      48 bytes  x 30")) << run.output;
  EXPECT_TRUE(has_line(run.output, "udp datagrams: 222 (incomplete fragment sets dropped: 0, conflicting: 0)"))
      << run.output;
  EXPECT_EQ(run.output.find("lidar packets"), std::string::npos) << "no metadata, no decoding";
}

TEST(CliPcapInfo, DecodesFramesWithMetadata) {
  const CliRun run = run_cli("pcap-info " + kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap --metadata " + kSamples +
                             "OS-1-128_v2.3.0_1024x10.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(has_line(run.output, "lidar packets: 192 (8448 bytes on port 7502)")) << run.output;
  EXPECT_TRUE(has_line(run.output, "frames: 3")) << run.output;
  EXPECT_TRUE(has_line(run.output, "valid columns per frame: 1024")) << run.output;
  EXPECT_TRUE(has_line(run.output, "imu packets: 30")) << run.output;
  // FW 2.3 sends the 0xDEADBEEF0000C0DE marker instead of a CRC (protocol doc 4.5).
  EXPECT_TRUE(has_line(run.output, "crc failures: 0 (valid crc: 0, no crc: 192)")) << run.output;
  EXPECT_NE(run.output.find("profile: RNG15_RFL8_NIR8"), std::string::npos) << run.output;
}

// A dual-return capture: the share of returns with a second one (what the shipped profiles' mixed
// pixels are judged against), and single-return profiles say nothing of second returns.
TEST(CliPcapInfo, CountsSecondReturnsOfDualProfiles) {
  const CliRun dual = run_cli("pcap-info " + kSamples + "OS-0-32-U1_v2.2.0_1024x10.pcap --metadata " + kSamples +
                              "OS-0-32-U1_v2.2.0_1024x10.json");
  ASSERT_EQ(dual.exit_code, 0) << dual.output;
  EXPECT_TRUE(has_line(dual.output, "second returns: 0.0080 of returns (range2 != 0: 172)")) << dual.output;
  const CliRun single = run_cli("pcap-info " + kSamples + "crc_test.pcap --metadata " + kSamples + "crc_test.json");
  ASSERT_EQ(single.exit_code, 0) << single.output;
  EXPECT_EQ(single.output.find("second returns"), std::string::npos) << single.output;
}

TEST(CliPcapInfo, ChecksCrcsOfFirmware32Packets) {
  // README: crc_test.pcap, 512x10, 34 lidar packets with valid CRC-64 footers, 10 IMU.
  const CliRun run = run_cli("pcap-info " + kSamples + "crc_test.pcap --metadata " + kSamples + "crc_test.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(has_line(run.output, "lidar packets: 34 (8448 bytes on port 7502)")) << run.output;
  EXPECT_TRUE(has_line(run.output, "crc failures: 0 (valid crc: 34, no crc: 0)")) << run.output;
  EXPECT_TRUE(has_line(run.output, "imu packets: 10")) << run.output;
}

TEST(CliPcapInfo, WindowedCaptureHasTheWindowsColumns) {
  // windowed_frame1: azimuth window [180000, 360000] -> column_window [1, 256] of 512: 256 valid
  // columns, 17 packets, sent to port 53750 rather than the metadata's lidar port.
  const CliRun run =
      run_cli("pcap-info " + kSamples + "windowed_frame1.pcap --metadata " + kSamples + "windowed_frame1_0.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("lidar packets: 17 (8448 bytes on port 53750"), std::string::npos) << run.output;
  EXPECT_TRUE(has_line(run.output, "valid columns per frame: 256")) << run.output;
}

TEST(CliPcapInfo, SeparatesTwoSensorsOnOnePort) {
  // same_ports_nonlegacy: OS-0-128 (FUSA dual) and OS-1-64-AH (RNG19 dual), both 16640-byte packets
  // on 7502: with the first sensor's metadata, the other one's packet is skipped by prod_sn/init_id.
  const CliRun run = run_cli("pcap-info " + kSamples + "same_ports_nonlegacy.pcap --metadata " + kSamples +
                             "same_ports_nonlegacy.1.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(has_line(run.output, "lidar packets: 1 (16640 bytes on port 7502)")) << run.output;
  EXPECT_NE(run.output.find("init_id differ): 1 packets"), std::string::npos) << run.output;
}

TEST(CliPcapInfo, ReportsLidarOffForAnImuOnlyCapture) {
  const CliRun run =
      run_cli("pcap-info " + kSamples + "imu_zm_no_lidar.pcap --metadata " + kSamples + "imu_zm_no_lidar_0.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(has_line(run.output, "  port  7513     452 bytes  x 8")) << run.output;
  EXPECT_NE(run.output.find("lidar: off"), std::string::npos) << run.output;
}

TEST(CliPcapInfo, MissingOrCorruptInputExitsWith2) {
  const CliRun missing = run_cli("pcap-info /nonexistent/capture.pcap");
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(missing.output.find("/nonexistent/capture.pcap"), std::string::npos) << missing.output;

  const std::string corrupt =
      std::filesystem::temp_directory_path() / ("lidartwin_corrupt_" + std::to_string(getpid()) + ".pcap");
  {
    std::ifstream in(kSamples + "crc_test.pcap", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(corrupt, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  // Cut in half (a recording interrupted): read as far as it is whole, and said so.
  const CliRun truncated = run_cli("pcap-info " + corrupt);
  EXPECT_EQ(truncated.exit_code, 0) << truncated.output;
  EXPECT_NE(truncated.output.find("cut short: the file ends inside record "), std::string::npos) << truncated.output;
  // Not a capture at all (its magic number overwritten): refused, naming the file.
  {
    std::fstream file(corrupt, std::ios::binary | std::ios::in | std::ios::out);
    file.write("JUNK", 4);
  }
  const CliRun garbage = run_cli("pcap-info " + corrupt);
  EXPECT_EQ(garbage.exit_code, 2) << garbage.output;
  EXPECT_NE(garbage.output.find(corrupt), std::string::npos) << garbage.output;
  std::filesystem::remove(corrupt);

  const CliRun bad_metadata =
      run_cli("pcap-info " + kSamples + "crc_test.pcap --metadata " + kSamples + "crc_test.pcap");
  EXPECT_EQ(bad_metadata.exit_code, 2) << bad_metadata.output;
  EXPECT_NE(bad_metadata.output.find("not valid JSON"), std::string::npos) << bad_metadata.output;
}

}  // namespace

}  // namespace cli_pcap_info_test
