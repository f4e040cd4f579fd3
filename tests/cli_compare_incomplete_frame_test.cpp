// A capture that stops mid-frame (a recording ended before the frame's last packets came): the
// columns it never received are absent, not dark. compare leaves them out of every bin, counts
// them in report.json's inputs and says so; scored as misses, they had made a detection failure
// of the last frame's time bin.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/cli_run.h"

namespace cli_compare_incomplete_frame_test {

namespace fs = std::filesystem;

namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;

using lidartwin::test::CliRun;
using lidartwin::test::run_cli;

// Where each of the pcap's records (16-byte header, then incl_len bytes) begins, after its 24-byte
// file header.
std::vector<size_t> record_offsets(const std::string& bytes) {
  std::vector<size_t> out;
  for (size_t at = 24; at + 16 <= bytes.size();) {
    uint32_t length = 0;
    for (int k = 3; k >= 0; --k) length = length << 8 | static_cast<uint8_t>(bytes[at + 8 + static_cast<size_t>(k)]);
    out.push_back(at);
    at += 16 + length;
  }
  return out;
}

TEST(CompareIncompleteFrame, ColumnsACaptureNeverReceivedAreLeftOutAndCounted) {
  const fs::path dir = fs::path(testing::TempDir()) / ("incomplete_frame_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string scene = kSource + "/scenes/calibration_hall.glb";
  const CliRun recorded =
      run_cli("record --profile os1-64 --mode 512x10 --scene " + scene + " --trajectory " + kSource +
              "/scenes/calibration_hall_static.tum --frames 3 --seed 5 --out " + (dir / "capture").string());
  ASSERT_EQ(recorded.exit_code, 0) << recorded.output;

  // Stop the recording inside its last frame: keep 85 % of its records (lidar packets are IP
  // fragments, a few records each; IMU packets one), so about half the last frame's packets go.
  const fs::path pcap = dir / "capture" / "capture.pcap";
  std::string bytes;
  {
    std::ifstream in(pcap, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::vector<size_t> records = record_offsets(bytes);
  ASSERT_GT(records.size(), 100u);
  std::ofstream(pcap, std::ios::binary | std::ios::trunc) << bytes.substr(0, records[records.size() * 85 / 100]);

  const fs::path out = dir / "report";
  const CliRun compared = run_cli("compare --no-plots --capture " + (dir / "capture").string() + " --scene " + scene +
                                  " --profile os1-64 --out " + out.string());
  ASSERT_EQ(compared.exit_code, 0) << compared.output;
  std::ifstream in(out / "report.json");
  const nlohmann::json report = nlohmann::json::parse(in);
  // Packets of 16 columns, about half of the last frame's 512: whole packets, within that frame.
  const size_t absent = report["inputs"]["columns_not_received"].get<size_t>();
  EXPECT_EQ(absent % 16, 0u);
  EXPECT_GT(absent, 128u);
  EXPECT_LT(absent, 512u);
  EXPECT_NE(compared.output.find("note: " + std::to_string(absent) +
                                 " columns of the 3 frames read never arrived (packets lost, outside the azimuth "
                                 "window, or after the recording stopped): left out, not scored as misses"),
            std::string::npos)
      << compared.output;
  EXPECT_EQ(report["summary"]["frames"], 3);
  // Every pixel of the columns that came, and none of the others.
  EXPECT_EQ(report["summary"]["pixels"], (3 * 512 - absent) * 64) << report["summary"].dump();
  EXPECT_EQ(report["summary"]["impossible_misses"], 0);
  fs::remove_all(dir);
}

}  // namespace

}  // namespace cli_compare_incomplete_frame_test
