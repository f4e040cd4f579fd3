// `lidartwin record` rejects bad flags with exit code 2 and a message naming the flag.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/record_capture.h"

namespace lidartwin::cli_record_flags_test {
namespace {

using ::testing::HasSubstr;

const std::string kScene = std::string(LIDARTWIN_SOURCE_DIR) + "/scenes/calibration_hall.glb";

struct Outcome {
  int code;
  std::string error;
};

Outcome record(const std::string& flags) {
  const auto dir = std::filesystem::temp_directory_path() / ("lidartwin_flags_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto err = dir / "stderr.txt";
  const int code = test::run_lidartwin("record --scene " + kScene + " --out " + (dir / "out").string() + " " + flags +
                                       " 2> " + err.string());
  std::ifstream in(err);
  Outcome outcome{code, {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()}};
  std::filesystem::remove_all(dir);
  return outcome;
}

TEST(RecordFlags, ModeMustBeOneOfTheProfiles) {
  const Outcome o = record("--profile os1-64 --pose \"0 0 4 0 0 0 1\" --mode 4096x5");
  EXPECT_EQ(o.code, 2);
  EXPECT_THAT(o.error, HasSubstr("--mode 4096x5"));
  EXPECT_THAT(o.error, HasSubstr("2048x10"));
}

TEST(RecordFlags, BadPoseNamesTheFlagAndTheText) {
  const Outcome o = record("--profile os1-64 --pose \"0 0 4 0 0 0 0\"");
  EXPECT_EQ(o.code, 2);
  EXPECT_THAT(o.error, HasSubstr("--pose"));
  EXPECT_THAT(o.error, HasSubstr("zero norm"));
}

TEST(RecordFlags, NeedsAPoseOrATrajectory) {
  const Outcome o = record("--profile os1-64");
  EXPECT_EQ(o.code, 2);
  EXPECT_THAT(o.error, HasSubstr("--trajectory or --pose"));
}

TEST(RecordFlags, CliChecksNameTheFlag) {
  for (const std::string bad : {"--udp-profile FOO", "--columns-per-packet 3", "--frames 0", "--mode 1000x10"}) {
    const Outcome o = record("--profile os1-64 --pose \"0 0 4 0 0 0 1\" " + bad);
    EXPECT_NE(o.code, 0) << bad;
    EXPECT_THAT(o.error, HasSubstr(bad.substr(0, bad.find(' ')))) << bad;
  }
}

}  // namespace
}  // namespace lidartwin::cli_record_flags_test
