// E14's fingerprint in recorded data: with false_alarms in the profile, a sunny recording of the
// plant flight gains isolated points only where the same recording without it has no return, at a
// rate that follows each pixel's NEAR_IR, with ranges uniform over the effect's window (a
// Kolmogorov-Smirnov test) and the low SIGNAL of a noise peak. Both recordings use the same seed;
// false_alarms is appended to the chain so the other effects keep their random streams.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_false_alarms_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::edited_profile;
using lidartwin::test::run_lidartwin;

namespace {

const fs::path kSource = LIDARTWIN_SOURCE_DIR;
constexpr double kProbability = 0.05;  // at the sky's NEAR_IR
constexpr double kSkyPhotons = 1500.0;
constexpr double kMaxRangeM = 60.0;
constexpr uint32_t kAlarmSignal = 3;

// profiles/os1-64.json under a bright sky, with or without false alarms.
fs::path profile(bool alarms) {
  return edited_profile("os1-64", alarms ? "sunny-alarms" : "sunny", [&](nlohmann::json& effects) {
    effects.at(0)["ambient_photons"] = 800.0;
    effects.at(0)["sky_photons"] = kSkyPhotons;
    if (!alarms) return;
    effects.push_back({{"name", "false_alarms"},
                       {"probability_at_reference", kProbability},
                       {"reference_near_ir_photons", kSkyPhotons},
                       {"max_range_m", kMaxRangeM},
                       {"signal_photons", static_cast<double>(kAlarmSignal)}});
  });
}

fs::path record(bool alarms) {
  const fs::path dir = fs::path(testing::TempDir()) / (alarms ? "false_alarms_on" : "false_alarms_off");
  fs::remove_all(dir);
  const std::string args = "record --profile " + profile(alarms).string() + " --scene " +
                           (kSource / "scenes/plant.glb").string() + " --trajectory " +
                           (kSource / "scenes/plant_inspection.tum").string() +
                           " --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16 --frames 2 --seed 8 --out " +
                           dir.string() + " > /dev/null 2>&1";
  EXPECT_EQ(run_lidartwin(args), 0) << args;
  return dir;
}

TEST(RecordFalseAlarms, IsolatedPointsAppearWhereNothingReturnedAtTheAmbientRate) {
  const auto plain = decode_capture(record(false));
  const auto sunny = decode_capture(record(true));
  ASSERT_EQ(plain.frames.size(), 2u);
  ASSERT_EQ(sunny.frames.size(), 2u);
  size_t returns_changed = 0, empty = 0, alarms = 0, wrong_signal = 0;
  double expected = 0.0, variance = 0.0;
  std::vector<double> ranges;
  for (const auto& [frame_id, before] : plain.frames) {
    const Scan& after = sunny.frames.at(frame_id);
    for (int c = 0; c < before.width; ++c) {
      for (int r = 0; r < before.height; ++r) {
        const uint32_t range_before = before.at(ChannelField::kRange, c, r);
        const uint32_t range_after = after.at(ChannelField::kRange, c, r);
        if (range_before != 0) {
          returns_changed += range_after != range_before ||
                             after.at(ChannelField::kSignal, c, r) != before.at(ChannelField::kSignal, c, r);
          continue;
        }
        ++empty;
        const double p = std::min(1.0, kProbability * before.at(ChannelField::kNearIr, c, r) / kSkyPhotons);
        expected += p;
        variance += p * (1.0 - p);
        if (range_after == 0) continue;
        ++alarms;
        ranges.push_back(range_after * 1e-3);
        wrong_signal += after.at(ChannelField::kSignal, c, r) != kAlarmSignal;
      }
    }
  }
  // Kolmogorov-Smirnov distance of the alarm ranges from U(0, max_range_m].
  std::sort(ranges.begin(), ranges.end());
  double ks = 0.0;
  const auto n = static_cast<double>(ranges.size());
  for (size_t i = 0; i < ranges.size(); ++i) {
    const double cdf = ranges[i] / kMaxRangeM;
    ks = std::max({ks, std::abs(cdf - static_cast<double>(i) / n), std::abs(cdf - static_cast<double>(i + 1) / n)});
  }
  const double ks_critical = 1.63 / std::sqrt(n);  // 1 % level
  std::printf("pixels without a return %zu: false alarms %zu vs %.1f expected (%+.1f sd); KS %.4f (1 %% level %.4f)\n",
              empty, alarms, expected, (static_cast<double>(alarms) - expected) / std::sqrt(variance), ks, ks_critical);
  EXPECT_GT(empty, 20'000u) << "the flight sees sky";
  EXPECT_EQ(returns_changed, 0u) << "false alarms only fill pixels without a return";
  EXPECT_NEAR(static_cast<double>(alarms), expected, 5.0 * std::sqrt(variance));
  EXPECT_LT(ks, ks_critical);
  EXPECT_EQ(wrong_signal, 0u);
}

}  // namespace

}  // namespace cli_record_false_alarms_test
