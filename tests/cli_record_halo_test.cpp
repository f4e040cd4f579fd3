// E8's fingerprint in recorded data: beside the calibration hall's retroreflective panels, in their
// own columns, returns appear at the panel's range at the rate predicted for their distance in
// rows, and nowhere else. Same seed with and without the halo; it is appended to the chain so the
// other effects keep their random streams.
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_halo_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::edited_profile;
using lidartwin::test::record_hall;

namespace {

constexpr double kProbability = 0.4;
constexpr double kDecayRows = 2.0;
constexpr uint32_t kHaloSignal = 60000;  // stronger than any surface: the halo is the first return
constexpr int kReach = 8;                // IdealReturn::kRetroReachRows

fs::path record(bool halo) {
  const std::string name = halo ? "halo_on" : "halo_off";
  const fs::path profile = edited_profile("os1-64", name, [&](nlohmann::json& effects) {
    if (!halo) return;
    effects.push_back({{"name", "halo"},
                       {"probability", kProbability},
                       {"decay_rows", kDecayRows},
                       {"range_sigma_m", 0.02},
                       {"signal_photons", static_cast<double>(kHaloSignal)}});
  });
  return record_hall(name, "--profile " + profile.string() +
                               " --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16 --frames 2 --seed 8");
}

TEST(RecordHalo, ReturnsAtTheRetroreflectorsRangeBesideItInItsColumn) {
  const auto clear = decode_capture(record(false));
  const auto haloed = decode_capture(record(true));
  ASSERT_EQ(clear.frames.size(), 2u);
  ASSERT_EQ(haloed.frames.size(), 2u);
  // By rows from the nearest retroreflective pixel of the column (REFLECTIVITY above 100 in the
  // clear recording): pixels, halo returns seen, halo returns expected and their variance.
  std::array<double, kReach + 1> pixels{}, seen{}, expected{}, variance{};
  size_t far_halos = 0, off_range = 0;
  for (const auto& [frame_id, before] : clear.frames) {
    const Scan& after = haloed.frames.at(frame_id);
    for (int c = 0; c < before.width; ++c) {
      const auto retro = [&](int r) {
        return before.at(ChannelField::kRange, c, r) != 0 && before.at(ChannelField::kReflectivity, c, r) > 100;
      };
      for (int r = 0; r < before.height; ++r) {
        if (retro(r)) continue;
        int rows = 0, source = -1;
        for (int d = 1; d <= kReach && source < 0; ++d) {
          if (r - d >= 0 && retro(r - d)) source = r - d;
          else if (r + d < before.height && retro(r + d)) source = r + d;
          rows = d;
        }
        const bool halo = after.at(ChannelField::kSignal, c, r) == kHaloSignal;
        if (source < 0) {
          far_halos += halo;
          continue;
        }
        const double p = kProbability * std::exp(-(rows - 1) / kDecayRows);
        pixels[static_cast<size_t>(rows)] += 1;
        expected[static_cast<size_t>(rows)] += p;
        variance[static_cast<size_t>(rows)] += p * (1.0 - p);
        if (!halo) continue;
        seen[static_cast<size_t>(rows)] += 1;
        // The panel's range, give or take the halo's 2 cm and the panel's own range noise.
        const double step = std::abs(static_cast<double>(after.at(ChannelField::kRange, c, r)) -
                                     static_cast<double>(before.at(ChannelField::kRange, c, source)));
        off_range += step > 150.0;
      }
    }
  }
  for (int d = 1; d <= kReach; ++d) {
    const auto k = static_cast<size_t>(d);
    std::printf("  %d rows from a retroreflector: %5.0f pixels, %4.0f halo returns, %6.1f expected (%+.1f se)\n", d,
                pixels[k], seen[k], expected[k], (seen[k] - expected[k]) / std::sqrt(std::max(variance[k], 1.0)));
    EXPECT_NEAR(seen[k], expected[k], 5.0 * std::sqrt(variance[k]) + 1.0) << d << " rows";
  }
  ASSERT_GT(expected[1], 100.0) << "the hall's panels should give enough pixels beside them";
  EXPECT_EQ(far_halos, 0u) << "halo returns farther than 8 rows from a retroreflector";
  EXPECT_EQ(off_range, 0u) << "halo returns away from their retroreflector's range";
}

}  // namespace

}  // namespace cli_record_halo_test
