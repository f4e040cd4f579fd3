// E11's fingerprint in recorded data: a shaking mount moves whole columns, since all beams of a
// column fire at once. From the calibration hall's static pose, with vertical translation jitter
// only, the floor seen in each column (placed with the trajectory's pose, as a user would) sits
// one common height off, shared by every beam of the column to the millimetre, and those heights
// spread over the columns by translation_rms_m. Same seed with and without vibration; it is
// appended to the chain so the other effects keep their random streams.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_vibration_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::edited_profile;
using lidartwin::test::record_hall;
using lidartwin::test::SdkIntrinsics;

namespace {

constexpr double kTranslationRms = 0.02;
constexpr double kSensorHeight = 4.0;  // kHallPose

fs::path record(bool shaking) {
  const std::string name = shaking ? "vibration_on" : "vibration_off";
  const fs::path profile = edited_profile("os1-64", name, [&](nlohmann::json& effects) {
    if (!shaking) return;
    effects.push_back({{"name", "vibration"},
                       {"angular_rms_deg", 0.0},
                       {"translation_rms_m", kTranslationRms},
                       {"band_low_hz", 50.0},
                       {"band_high_hz", 500.0}});
  });
  return record_hall(name, "--profile " + profile.string() +
                               " --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16 --frames 10 --seed 9");
}

TEST(RecordVibration, WholeColumnsMoveTogetherBySpreadOfTheJitter) {
  const fs::path still_dir = record(false), shaking_dir = record(true);
  const auto still = decode_capture(still_dir);
  const auto shaking = decode_capture(shaking_dir);
  const SdkIntrinsics beams = SdkIntrinsics::load(still_dir / "metadata.json");
  ASSERT_EQ(still.frames.size(), 10u);
  ASSERT_EQ(shaking.frames.size(), 10u);
  // Per column: the mean height change of its floor pixels, and their spread about it.
  std::vector<double> column_shift;
  double within_sum2 = 0.0;
  size_t within_n = 0;
  for (const auto& [frame_id, before] : still.frames) {
    const Scan& after = shaking.frames.at(frame_id);
    for (int c = 0; c < before.width; ++c) {
      std::vector<double> dz;
      for (int r = 0; r < before.height; ++r) {
        const uint32_t r0 = before.at(ChannelField::kRange, c, r), r1 = after.at(ChannelField::kRange, c, r);
        if (r0 == 0 || r1 == 0 || r0 > 30000) continue;
        // The floor, at z = 0 in the hall (range noise puts it within a few mm), before and after:
        // a shaken beam that slips onto a board's foot measures the board.
        const double z0 = beams.point(r, c, r0).z() + kSensorHeight, z1 = beams.point(r, c, r1).z() + kSensorHeight;
        if (std::abs(z0) > 0.02 || std::abs(z1) > 0.15) continue;
        dz.push_back(z1 - z0);
      }
      if (dz.size() < 8) continue;
      double mean = 0.0;
      for (const double d : dz) mean += d;
      mean /= static_cast<double>(dz.size());
      column_shift.push_back(mean);
      for (const double d : dz) within_sum2 += (d - mean) * (d - mean);
      within_n += dz.size() - 1;
    }
  }
  ASSERT_GT(column_shift.size(), 8000u) << "the floor should be seen in most columns";
  double sum2 = 0.0;
  for (const double s : column_shift) sum2 += s * s;
  const double between = std::sqrt(sum2 / static_cast<double>(column_shift.size()));
  const double within = std::sqrt(within_sum2 / static_cast<double>(within_n));
  std::printf(
      "floor height change over %zu columns: RMS %.4f m between columns (translation_rms_m %.3f), %.5f m within a "
      "column\n",
      column_shift.size(), between, kTranslationRms, within);
  // 1 s of a 50-500 Hz jitter: the sample RMS is within a few percent of the long-run one.
  EXPECT_NEAR(between, kTranslationRms, 0.1 * kTranslationRms);
  EXPECT_LT(within, 0.002) << "every beam of a column fires from the same pose";
}

}  // namespace

}  // namespace cli_record_vibration_test
