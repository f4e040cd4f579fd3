// Acceptance: noise is keyed by (seed, frame, column, beam, effect), never by thread, so a seed
// gives the same capture byte for byte with any thread count; another seed gives other noise.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "support/record_capture.h"

namespace lidartwin {
namespace {

const std::filesystem::path kSource = LIDARTWIN_SOURCE_DIR;

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class RecordDeterminism : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lidartwin_determinism_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // The plant flight with the profile's full noise chain: moving poses, noise, dropout.
  std::filesystem::path record(const std::string& name, int seed, int threads) {
    const auto out = dir_ / name;
    const std::string arguments =
        "record --profile os1-64 --mode 1024x10 --frames 3 --scene " + (kSource / "scenes/plant.glb").string() +
        " --trajectory " + (kSource / "scenes/plant_inspection.tum").string() + " --seed " + std::to_string(seed) +
        " --threads " + std::to_string(threads) + " --out " + out.string();
    EXPECT_EQ(test::run_lidartwin(arguments), 0) << arguments;
    return out;
  }

  std::filesystem::path dir_;
};

TEST_F(RecordDeterminism, SameSeedGivesIdenticalBytesForAnyThreadCount) {
  const auto one = record("one_thread", 11, 1);
  const auto two = record("two_threads", 11, 2);
  const std::string capture = file_bytes(one / "capture.pcap");
  ASSERT_GT(capture.size(), 1'000'000u);
  EXPECT_TRUE(capture == file_bytes(two / "capture.pcap")) << "capture.pcap differs between 1 and 2 threads";
  EXPECT_EQ(file_bytes(one / "metadata.json"), file_bytes(two / "metadata.json"));
  EXPECT_EQ(file_bytes(one / "poses.tum"), file_bytes(two / "poses.tum"));
}

TEST_F(RecordDeterminism, AnotherSeedGivesOtherNoise) {
  const auto a = test::decode_capture(record("seed_a", 11, 2));
  const auto b = test::decode_capture(record("seed_b", 12, 2));
  ASSERT_EQ(a.frames.size(), 3u);
  ASSERT_EQ(b.frames.size(), 3u);
  size_t returns = 0, different = 0;
  for (const auto& [frame_id, scan] : a.frames) {
    const auto& ranges_a = scan.channels[static_cast<size_t>(ChannelField::kRange)];
    const auto& ranges_b = b.frames.at(frame_id).channels[static_cast<size_t>(ChannelField::kRange)];
    ASSERT_EQ(ranges_a.size(), ranges_b.size());
    for (size_t i = 0; i < ranges_a.size(); ++i) {
      returns += ranges_a[i] != 0;
      different += ranges_a[i] != ranges_b[i];
    }
  }
  ASSERT_GT(returns, 10'000u);
  // Range noise is millimetres to centimetres on a 1 mm wire step: most returns change.
  EXPECT_GT(different, returns / 2) << different << " of " << returns << " returns differ";
}

}  // namespace
}  // namespace lidartwin
