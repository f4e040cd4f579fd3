// Acceptance: noise is keyed by (seed, frame, column, beam, effect), never by thread, so a seed
// gives the same capture byte for byte with any thread count; another seed gives other noise.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/every_effect_chain.h"
#include "support/record_capture.h"

namespace lidartwin::cli_record_determinism_test {
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
  std::filesystem::path record(const std::string& name, int seed, int threads, const std::string& profile = "os1-64",
                               const std::string& extra = "") {
    const auto out = dir_ / name;
    const std::string arguments = "record --profile " + profile + extra + " --mode 1024x10 --frames 3 --scene " +
                                  (kSource / "scenes/plant.glb").string() + " --trajectory " +
                                  (kSource / "scenes/plant_inspection.tum").string() + " --seed " +
                                  std::to_string(seed) + " --threads " + std::to_string(threads) + " --out " +
                                  out.string();
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

// Every library effect on at once, in a DUAL profile (second returns from mixed_pixels and the
// window's near returns, edge partners cast beside each block): still the same bytes.
TEST_F(RecordDeterminism, EveryEffectOnGivesIdenticalBytesForAnyThreadCount) {
  std::ifstream in(kSource / "profiles/os1-64.json");
  nlohmann::json profile = nlohmann::json::parse(in);
  profile["effects"] = test::every_effect_chain(
      {{"name", "range_noise_linear"}, {"sigma0_m", 0.01}, {"sigma_max_m", 0.15}, {"range_max_m", 100.0}});
  const auto path = dir_ / "every_effect.json";
  std::ofstream(path) << profile.dump(2);
  const std::string dual = " --udp-profile RNG19_RFL8_SIG16_NIR16_DUAL";
  const auto one = record("every_one_thread", 5, 1, path.string(), dual);
  const auto two = record("every_two_threads", 5, 2, path.string(), dual);
  const std::string capture = file_bytes(one / "capture.pcap");
  ASSERT_GT(capture.size(), 1'000'000u);
  EXPECT_TRUE(capture == file_bytes(two / "capture.pcap")) << "capture.pcap differs between 1 and 2 threads";
  size_t second_returns = 0;
  for (const auto& [frame_id, scan] : test::decode_capture(one).frames) {
    for (const uint32_t range2 : scan.channels[static_cast<size_t>(ChannelField::kRange2)])
      second_returns += range2 != 0;
  }
  EXPECT_GT(second_returns, 1000u) << "the every-effect chain makes second returns";
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
}  // namespace lidartwin::cli_record_determinism_test
