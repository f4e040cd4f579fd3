// What the shipped datasheet profiles record since real captures refitted them (profiles/*.json,
// each effect's "source"): a range spread that depends on signal, as a real sensor's does (E2,
// signal_precision, fitted on the real OS-1-128 and OS-0-128 samples), and second returns in DUAL
// captures (E6/E15, mixed_pixels), at the rates real DUAL sensors report.
// Method: the calibration hall recorded from its static pose, once ideal and over many frames
// noisy; a pixel's residual is noisy - ideal. Each profile is compared with itself without the
// effect under test, so the hall's own geometry (incidence, range) cancels.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_shipped_profile_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::record_hall;

namespace {

// profiles/<shipped>.json without the effects `removed`, as <temporary directory>/<name>.json.
fs::path shipped_without(const std::string& shipped, const std::vector<std::string>& removed, const std::string& name) {
  std::ifstream in(std::string(LIDARTWIN_SOURCE_DIR) + "/profiles/" + shipped + ".json");
  nlohmann::json profile = nlohmann::json::parse(in);
  nlohmann::json kept = nlohmann::json::array();
  size_t found = 0;
  for (const auto& effect : profile.at("effects")) {
    if (std::find(removed.begin(), removed.end(), effect.at("name")) != removed.end()) {
      ++found;
    } else {
      kept.push_back(effect);
    }
  }
  EXPECT_EQ(found, removed.size()) << shipped << " lacks one of the effects to remove";
  profile["effects"] = kept;
  const fs::path path = fs::path(testing::TempDir()) / (name + ".json");
  std::ofstream(path) << profile.dump(2);
  return path;
}

// The residual spread of the weakest and the strongest returns (a quarter each, by measured SIGNAL)
// among the hall's pixels at 3-15 m, where Table I is one sigma (1 cm).
struct SpreadBySignal {
  double weak_m = 0.0;
  double strong_m = 0.0;
};

SpreadBySignal spread_by_signal(const std::string& profile, const std::string& name) {
  const auto ideal = decode_capture(
      record_hall("shipped_" + name + "_ideal", "--profile " + profile + " --mode 512x10 --frames 1 --seed 5 --ideal"));
  const auto noisy = decode_capture(
      record_hall("shipped_" + name + "_noisy", "--profile " + profile + " --mode 512x10 --frames 12 --seed 5"));
  EXPECT_FALSE(ideal.frames.empty());
  const Scan& truth = ideal.frames.begin()->second;
  struct Sample {
    double signal, residual;
  };
  std::vector<Sample> samples;
  for (const auto& [id, scan] : noisy.frames) {
    for (int c = 0; c < scan.width; ++c) {
      for (int r = 0; r < scan.height; ++r) {
        const double want = truth.at(ChannelField::kRange, c, r) * 1e-3;
        const double got = scan.at(ChannelField::kRange, c, r) * 1e-3;
        if (want < 3.0 || want > 15.0 || got == 0.0) continue;
        samples.push_back({static_cast<double>(scan.at(ChannelField::kSignal, c, r)), got - want});
      }
    }
  }
  EXPECT_GT(samples.size(), 20000u);
  std::sort(samples.begin(), samples.end(), [](const Sample& a, const Sample& b) { return a.signal < b.signal; });
  // Robust: 1.4826 times the median absolute residual, so that flying points at depth edges (E6)
  // and pixels whose surface differs between frames do not decide it.
  const auto rms = [&](size_t begin, size_t end) {
    std::vector<double> magnitudes;
    for (size_t i = begin; i < end; ++i) magnitudes.push_back(std::abs(samples[i].residual));
    auto middle = magnitudes.begin() + static_cast<std::ptrdiff_t>(magnitudes.size() / 2);
    std::nth_element(magnitudes.begin(), middle, magnitudes.end());
    return 1.4826 * *middle;
  };
  const size_t quarter = samples.size() / 4;
  return {rms(0, quarter), rms(samples.size() - quarter, samples.size())};
}

// E2 and its tails in the shipped os1-64: the weakest quarter of the hall's returns spreads wider
// than without them, the strongest quarter as the datasheet says.
TEST(ShippedProfileRecord, RangeSpreadGrowsAsSignalFalls) {
  const SpreadBySignal shipped = spread_by_signal("os1-64", "os1_64");
  const SpreadBySignal without = spread_by_signal(
      shipped_without("os1-64", {"signal_precision", "signal_outliers"}, "os1_64_no_e2").string(), "os1_64_no_e2");
  // In the hall the weakest quarter is 2.1 times as wide as the strongest without E2 and its tails
  // (incidence), 2.4 times with them; the strongest keep the datasheet's 1 cm.
  EXPECT_GT(shipped.weak_m, 1.08 * without.weak_m)
      << "weak " << shipped.weak_m << " strong " << shipped.strong_m << "; without E2: weak " << without.weak_m
      << " strong " << without.strong_m;
  EXPECT_NEAR(shipped.strong_m, without.strong_m, 0.05 * without.strong_m);
  EXPECT_NEAR(shipped.strong_m, 0.010, 0.001);
}

// The share of a DUAL capture's returns that carry a second return.
double second_return_share(const std::string& profile, const std::string& name) {
  const auto capture = decode_capture(
      record_hall("shipped_dual_" + name, "--profile " + profile +
                                              " --mode 1024x10 --udp-profile RNG19_RFL8_SIG16_NIR16_DUAL "
                                              "--frames 2 --seed 5"));
  size_t returns = 0, second = 0;
  for (const auto& [id, scan] : capture.frames) {
    for (int c = 0; c < scan.width; ++c) {
      for (int r = 0; r < scan.height; ++r) {
        returns += scan.at(ChannelField::kRange, c, r) != 0;
        second += scan.at(ChannelField::kRange2, c, r) != 0;
      }
    }
  }
  EXPECT_GT(returns, 10000u);
  return static_cast<double>(second) / static_cast<double>(std::max<size_t>(returns, 1));
}

// Real DUAL sensors report second returns in 0.3 % (outdoors) to 6.7 % (close range) of pixels
// (the OS-0-32-U1 sample: 0.8 %, `lidartwin pcap-info` says); a DUAL capture with a shipped
// datasheet profile has them too, and without mixed pixels it has none.
TEST(ShippedProfileRecord, DualCapturesCarrySecondReturnsAtRealRates) {
  for (const std::string shipped : {"os0-32", "os1-64"}) {
    const double share = second_return_share(shipped, shipped);
    EXPECT_GT(share, 0.003) << shipped;
    EXPECT_LT(share, 0.067) << shipped;
  }
  const fs::path without = shipped_without("os1-64", {"mixed_pixels"}, "os1_64_no_e6");
  EXPECT_EQ(second_return_share(without.string(), "os1_64_no_e6"), 0.0);
}

}  // namespace

}  // namespace cli_record_shipped_profile_test
