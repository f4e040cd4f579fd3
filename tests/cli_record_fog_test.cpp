// E13's fingerprint in recorded data: in fog the calibration hall's SIGNAL falls as exp(-2 alpha r)
// (ln of the ratio to a clear recording is a line in range of slope -2 alpha), and soft-target
// returns appear in front of the surfaces, never behind. Same seed with and without fog; fog is
// appended to the chain so the other effects keep their random streams.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_fog_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::edited_profile;
using lidartwin::test::record_hall;

namespace {

constexpr double kAlpha = 0.04;
constexpr double kSoftProbability = 0.05;
constexpr uint32_t kSoftSignal = 60000;  // stronger than any wall: the soft return is the first

fs::path record(bool fog) {
  const std::string name = fog ? "fog_on" : "fog_off";
  const fs::path profile = edited_profile("os1-64", name, [&](nlohmann::json& effects) {
    if (!fog) return;
    effects.push_back({{"name", "fog"},
                       {"attenuation_per_m", kAlpha},
                       {"soft_return_probability", kSoftProbability},
                       {"soft_signal_photons", static_cast<double>(kSoftSignal)}});
  });
  return record_hall(name, "--profile " + profile.string() +
                               " --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16 --frames 2 --seed 6");
}

TEST(RecordFog, SignalFallsExponentiallyWithRangeAndSoftReturnsComeEarly) {
  const auto clear = decode_capture(record(false));
  const auto foggy = decode_capture(record(true));
  ASSERT_EQ(clear.frames.size(), 2u);
  ASSERT_EQ(foggy.frames.size(), 2u);
  size_t pixels = 0, soft = 0, soft_behind = 0, fitted = 0;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const auto& [frame_id, before] : clear.frames) {
    const Scan& after = foggy.frames.at(frame_id);
    for (int c = 0; c < before.width; ++c) {
      for (int r = 0; r < before.height; ++r) {
        const uint32_t range = before.at(ChannelField::kRange, c, r);
        if (range == 0) continue;
        ++pixels;
        if (after.at(ChannelField::kSignal, c, r) == kSoftSignal) {
          ++soft;
          // Drawn up to the surface's true range; the clear recording's range carries 1 cm of noise.
          soft_behind += after.at(ChannelField::kRange, c, r) > range + 50;
          continue;
        }
        const double s_clear = before.at(ChannelField::kSignal, c, r), s_fog = after.at(ChannelField::kSignal, c, r);
        if (s_clear < 200.0 || s_fog < 50.0) continue;  // whole counts: keep the ratio's rounding small
        const double x = range * 1e-3, y = std::log(s_fog / s_clear);
        ++fitted;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
      }
    }
  }
  const auto n = static_cast<double>(fitted);
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  const double rate = static_cast<double>(soft) / static_cast<double>(pixels);
  const double se = std::sqrt(kSoftProbability * (1.0 - kSoftProbability) / static_cast<double>(pixels));
  std::printf(
      "ln(S_fog / S_clear) against range over %zu pixels: slope %.4f per m (-2 alpha = %.4f); soft returns "
      "%.4f (expected %.2f, %+.1f se), %zu behind their surface\n",
      fitted, slope, -2.0 * kAlpha, rate, kSoftProbability, (rate - kSoftProbability) / se, soft_behind);
  ASSERT_GT(fitted, 5000u);
  EXPECT_NEAR(slope, -2.0 * kAlpha, 0.02 * 2.0 * kAlpha);
  EXPECT_NEAR(rate, kSoftProbability, 5.0 * se);
  EXPECT_EQ(soft_behind, 0u);
}

}  // namespace

}  // namespace cli_record_fog_test
