// Shot noise's fingerprint in recorded data: in a static recording of the calibration hall, each
// pixel's SIGNAL varies from frame to frame with variance F (S + B) (S its mean SIGNAL, B its
// NEAR_IR), and NEAR_IR with F B; without shot_noise both are the same in every frame.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_shot_noise_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::edited_profile;
using lidartwin::test::record_hall;

namespace {

constexpr double kExcessNoise = 2.0;
constexpr int kFrames = 8;

fs::path record(bool shot_noise) {
  const std::string name = shot_noise ? "shot_noise_on" : "shot_noise_off";
  const fs::path profile = edited_profile("os1-64", name, [&](nlohmann::json& effects) {
    effects.at(0)["ambient_photons"] = 400.0;
    if (shot_noise) effects.push_back({{"name", "shot_noise"}, {"excess_noise_factor", kExcessNoise}});
  });
  return record_hall(name, "--profile " + profile.string() + " --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16 " +
                               "--frames " + std::to_string(kFrames) + " --seed 4");
}

struct Spread {
  size_t pixels = 0;
  double signal_ratio = 0.0;   // mean over pixels of var(SIGNAL) / (S + B)
  double near_ir_ratio = 0.0;  // mean over pixels of var(NEAR_IR) / B
};

// Pixels returning in every frame with a mean SIGNAL above 50 photons (where the clamp at 0 and
// the wire's whole counts do not matter).
Spread temporal_spread(const lidartwin::test::DecodedCapture& capture) {
  Spread spread;
  const Scan& first = capture.frames.begin()->second;
  for (int c = 0; c < first.width; ++c) {
    for (int r = 0; r < first.height; ++r) {
      std::vector<double> signal, near_ir;
      for (const auto& [frame_id, scan] : capture.frames) {
        if (scan.at(ChannelField::kRange, c, r) == 0) break;
        signal.push_back(scan.at(ChannelField::kSignal, c, r));
        near_ir.push_back(scan.at(ChannelField::kNearIr, c, r));
      }
      if (signal.size() != capture.frames.size()) continue;
      const auto mean = [](const std::vector<double>& v) {
        double sum = 0.0;
        for (const double x : v) sum += x;
        return sum / static_cast<double>(v.size());
      };
      const auto variance = [&](const std::vector<double>& v) {
        const double m = mean(v);
        double sum = 0.0;
        for (const double x : v) sum += (x - m) * (x - m);
        return sum / static_cast<double>(v.size() - 1);
      };
      const double s = mean(signal), b = mean(near_ir);
      if (s < 50.0 || b < 50.0) continue;
      ++spread.pixels;
      spread.signal_ratio += variance(signal) / (s + b);
      spread.near_ir_ratio += variance(near_ir) / b;
    }
  }
  spread.signal_ratio /= static_cast<double>(spread.pixels);
  spread.near_ir_ratio /= static_cast<double>(spread.pixels);
  return spread;
}

TEST(RecordShotNoise, SignalVariesFrameToFrameAsExcessNoiseTimesPhotons) {
  const auto noisy = decode_capture(record(true));
  const auto plain = decode_capture(record(false));
  ASSERT_EQ(noisy.frames.size(), static_cast<size_t>(kFrames));
  ASSERT_EQ(plain.frames.size(), static_cast<size_t>(kFrames));
  const Spread with = temporal_spread(noisy), without = temporal_spread(plain);
  std::printf("pixels %zu: var(SIGNAL)/(S+B) %.3f, var(NEAR_IR)/B %.3f (F = %.1f); without shot_noise %.4f, %.4f\n",
              with.pixels, with.signal_ratio, with.near_ir_ratio, kExcessNoise, without.signal_ratio,
              without.near_ir_ratio);
  ASSERT_GT(with.pixels, 5000u);
  // Averaged over thousands of pixels the ratios are known to well under 5 %.
  EXPECT_NEAR(with.signal_ratio, kExcessNoise, 0.05 * kExcessNoise);
  EXPECT_NEAR(with.near_ir_ratio, kExcessNoise, 0.05 * kExcessNoise);
  EXPECT_EQ(without.signal_ratio, 0.0);
  EXPECT_EQ(without.near_ir_ratio, 0.0);
}

}  // namespace

}  // namespace cli_record_shot_noise_test
