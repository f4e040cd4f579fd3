// E16's fingerprint in recorded data: a dirty window over 90-150 degrees of encoder angle changes
// only the columns in that sector. Two recordings of the calibration hall with the same seed, one
// with profiles/os1-64.json and one with a window appended to its chain (appended, so the other
// effects keep their random streams): outside the sector every channel of every pixel is the
// same; inside, SIGNAL and REFLECTIVITY fall by the transmission, ranges stay, and near returns
// from the dirt replace a fifth of the pixels.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_window_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::edited_profile;
using lidartwin::test::record_hall;

namespace {

constexpr double kTransmission = 0.25;
constexpr double kNearProbability = 0.2;
constexpr uint32_t kNearRangeMm = 350;  // beyond os1-64's 0.3 m minimum range, nearer than any wall

fs::path record(bool window) {
  const fs::path profile = edited_profile("os1-64", window ? "window_on" : "window_off", [&](nlohmann::json& effects) {
    if (!window) return;
    effects.push_back({{"name", "window"},
                       {"sector_start_deg", 90.0},
                       {"sector_width_deg", 60.0},
                       {"transmission", kTransmission},
                       {"near_return_probability", kNearProbability},
                       {"near_return_range_m", kNearRangeMm * 1e-3},
                       {"near_return_signal_photons", 1e5}});  // stronger than any wall: first
  });
  return record_hall(window ? "window_on" : "window_off", "--profile " + profile.string() +
                                                              " --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16 "
                                                              "--frames 2 --seed 3");
}

// Measurement id m of 1024 sits at encoder angle 360 m / 1024: [90, 150) degrees is m = 256..426.
bool in_sector(int m) { return m >= 256 && m <= 426; }

TEST(RecordWindow, OnlyTheColumnsInItsSectorChange) {
  const auto plain = decode_capture(record(false));
  const auto dirty = decode_capture(record(true));
  ASSERT_EQ(plain.frames.size(), 2u);
  ASSERT_EQ(dirty.frames.size(), 2u);
  size_t outside_changed = 0, inside = 0, near = 0, range_changed = 0, signal_off = 0, reflectivity_off = 0;
  size_t dimmer = 0, compared = 0;
  for (const auto& [frame_id, before] : plain.frames) {
    ASSERT_TRUE(dirty.frames.count(frame_id)) << frame_id;
    const Scan& after = dirty.frames.at(frame_id);
    for (int c = 0; c < before.width; ++c) {
      for (int r = 0; r < before.height; ++r) {
        const auto value = [&](const Scan& scan, ChannelField field) { return scan.at(field, c, r); };
        if (!in_sector(c)) {
          for (const ChannelField field :
               {ChannelField::kRange, ChannelField::kReflectivity, ChannelField::kSignal, ChannelField::kNearIr}) {
            outside_changed += value(before, field) != value(after, field);
          }
          continue;
        }
        ++inside;
        if (value(after, ChannelField::kRange) == kNearRangeMm) {
          ++near;
          continue;
        }
        range_changed += value(after, ChannelField::kRange) != value(before, ChannelField::kRange);
        if (value(before, ChannelField::kRange) == 0) continue;
        ++compared;
        const double signal = value(before, ChannelField::kSignal);
        const double reflectivity = value(before, ChannelField::kReflectivity);
        // Both recordings round to whole counts: within one count of the attenuated value.
        signal_off += std::abs(static_cast<double>(value(after, ChannelField::kSignal)) - kTransmission * signal) > 1.0;
        if (reflectivity <= 100.0) {
          reflectivity_off += std::abs(static_cast<double>(value(after, ChannelField::kReflectivity)) -
                                       kTransmission * reflectivity) > 1.0;
        }
        dimmer += value(after, ChannelField::kSignal) < value(before, ChannelField::kSignal);
      }
    }
  }
  const double rate = static_cast<double>(near) / static_cast<double>(inside);
  const double se = std::sqrt(kNearProbability * (1.0 - kNearProbability) / static_cast<double>(inside));
  std::printf("sector pixels %zu: near returns %.4f (expected %.2f, %+.1f se); returns compared %zu, %zu dimmer\n",
              inside, rate, kNearProbability, (rate - kNearProbability) / se, compared, dimmer);
  EXPECT_EQ(outside_changed, 0u) << "pixel values outside the sector changed";
  EXPECT_NEAR(rate, kNearProbability, 5.0 * se);
  EXPECT_EQ(range_changed, 0u) << "the window changes no surface's range";
  EXPECT_GT(compared, 10'000u);
  EXPECT_EQ(signal_off, 0u);
  EXPECT_EQ(reflectivity_off, 0u);
  EXPECT_GT(dimmer, compared * 9 / 10);
}

}  // namespace

}  // namespace cli_record_window_test
