// `lidartwin record` stopped by SIGINT or SIGTERM ends after the frame it is rendering and leaves a
// complete capture of the frames before: every pcap record whole (the capture is written in 4 MiB
// blocks, which a killed process would cut mid-record), the ground truth files of those frames.
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pcap/pcap.h"
#include "support/record_capture.h"

namespace lidartwin::cli_record_interrupt_test {
namespace {

using ::testing::HasSubstr;

struct Interrupted {
  int exit_code = -1;
  std::string error;
};

// Starts a record far longer than the test, lets it write for a while, then sends `signal`.
Interrupted record_then(int signal, const std::filesystem::path& out) {
  const std::filesystem::path err = out.string() + ".stderr";
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, STDERR_FILENO);
    const std::string scene = std::string(LIDARTWIN_SOURCE_DIR) + "/scenes/calibration_hall.glb";
    execl(LIDARTWIN_BINARY, LIDARTWIN_BINARY, "record", "--profile", "os1-64", "--scene", scene.c_str(), "--pose",
          "0 0 1.5 0 0 0 1", "--frames", "1000000", "--threads", "1", "--out", out.c_str(), nullptr);
    _exit(127);
  }
  // Until several blocks are on disk (the first after about 4 MiB: some 20 frames of OS1-64).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  const auto written = [&out] {
    std::error_code missing;
    const std::uintmax_t size = std::filesystem::file_size(out / "capture.pcap", missing);
    return missing ? 0 : size;
  };
  while (written() < (std::uintmax_t{12} << 20) && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  kill(pid, signal);
  int status = 0;
  waitpid(pid, &status, 0);
  std::ifstream in(err);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status),
          {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()}};
}

class RecordInterrupted : public ::testing::TestWithParam<int> {};

TEST_P(RecordInterrupted, LeavesACompleteCaptureOfTheFramesBefore) {
  const auto out = std::filesystem::temp_directory_path() /
                   ("lidartwin_interrupt_" + std::to_string(getpid()) + "_" + std::to_string(GetParam()));
  std::filesystem::remove_all(out);
  const Interrupted run = record_then(GetParam(), out);
  EXPECT_EQ(run.exit_code, 130) << run.error;
  EXPECT_THAT(run.error, HasSubstr("interrupted after"));
  const auto poses = test::read_poses(out / "poses.tum");
  ASSERT_GE(poses.size(), 2u);
  const size_t frames = poses.size() - 1;  // a row per frame, and one where the last frame ends
  EXPECT_GE(frames, 15u);                  // 12 MiB were on disk: 15 frames of 64 packets of 13 KB
  EXPECT_LT(frames, 1000000u);
  // Every datagram whole (no record cut short), and every frame's 64 packets there (OS1-64 at
  // 1024x10: 1024 columns, 16 to a packet).
  PcapStats stats;
  const std::vector<UdpDatagram> datagrams = read_pcap(out / "capture.pcap", stats);
  EXPECT_EQ(stats.cut_short_record, 0u);
  EXPECT_EQ(stats.incomplete_datagrams, 0u);
  size_t lidar = 0;
  for (const UdpDatagram& d : datagrams) lidar += d.dst_port == 7502;
  EXPECT_EQ(lidar, frames * 64);
  // A fixed pose: no per-column poses (each would repeat poses.tum's).
  EXPECT_FALSE(std::filesystem::exists(out / "column_poses.tum"));
  std::filesystem::remove_all(out);
  std::filesystem::remove(out.string() + ".stderr");
}

INSTANTIATE_TEST_SUITE_P(Signals, RecordInterrupted, ::testing::Values(SIGINT, SIGTERM),
                         [](const ::testing::TestParamInfo<int>& signal) {
                           return std::string(signal.param == SIGINT ? "SIGINT" : "SIGTERM");
                         });

// The disk fills while recording (RLIMIT_FSIZE of 3 MB stands in for it, SIGXFSZ ignored so that
// the write fails as on a full disk; issue 27): record stops with an error naming the file, and what
// it wrote stays readable: the capture's whole records (the last may be cut), its metadata.
TEST(RecordDiskFull, SaysWhichFileAndWhatWasWrittenStaysReadable) {
  const auto out = std::filesystem::temp_directory_path() / ("lidartwin_disk_full_" + std::to_string(getpid()));
  std::filesystem::remove_all(out);
  const std::string scene = std::string(LIDARTWIN_SOURCE_DIR) + "/scenes/calibration_hall.glb";
  const std::string err = out.string() + ".stderr";
  const std::string command = "bash -c 'trap \"\" XFSZ; ulimit -f 3000; exec " + std::string(LIDARTWIN_BINARY) +
                              " record --profile os1-64 --scene " + scene +
                              " --pose \"0 0 1.5 0 0 0 1\" --frames 40 --threads 1 --out " + out.string() + "' 2>" +
                              err;
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0);
  std::ifstream in(err);
  const std::string error{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  EXPECT_THAT(error, HasSubstr((out / "capture.pcap").string() + ": cannot write capture: File too large"));
  PcapStats stats;
  const std::vector<UdpDatagram> datagrams = read_pcap(out / "capture.pcap", stats);
  size_t lidar = 0;
  for (const UdpDatagram& d : datagrams) lidar += d.dst_port == 7502;
  EXPECT_GE(lidar, 64u) << "a frame's packets at least (3 MB: some 3 frames)";
  std::printf("  %zu lidar packets readable; cut short at record %zu\n", lidar, stats.cut_short_record);
  EXPECT_NO_THROW(load_metadata(out / "metadata.json"));
  std::filesystem::remove_all(out);
  std::filesystem::remove(err);
}

}  // namespace
}  // namespace lidartwin::cli_record_interrupt_test
