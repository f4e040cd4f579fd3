// E6/E15's fingerprint in recorded data: with mixed_pixels in the profile, a DUAL recording of the
// calibration hall carries second returns, each at a depth edge of the scene and at the range of
// one of the two surfaces there; first returns between the surfaces appear only at edges too. The
// edges come from an ideal recording of the same pose (no effect but radiometry), found here with
// the caster's rule written out independently; without mixed_pixels there is no second return.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "support/record_capture.h"

namespace cli_record_mixed_pixels_test {

namespace fs = std::filesystem;
using lidartwin::ChannelField;
using lidartwin::Scan;
using lidartwin::test::decode_capture;
using lidartwin::test::edited_profile;
using lidartwin::test::record_hall;
using lidartwin::test::table_profile;

namespace {

const std::string kDual = "RNG19_RFL8_SIG16_NIR16_DUAL";

// profiles/os1-64.json (its table effects) with mixed_pixels after radiometry.
fs::path profile_with_mixed_pixels() {
  return edited_profile("os1-64", "os1-64-mixed", [](nlohmann::json& effects) {
    const nlohmann::json mixed = {{"name", "mixed_pixels"}, {"second_fraction", 0.05}};
    effects.insert(effects.begin() + 1, mixed);
  });
}

fs::path record(const std::string& profile, const std::string& name, int frames, bool ideal) {
  return record_hall("mixed_" + name, "--profile " + profile + " --mode 1024x10 --udp-profile " + kDual + " --frames " +
                                          std::to_string(frames) + " --seed 3" + (ideal ? " --ideal" : ""));
}

double range_at(const Scan& scan, ChannelField field, int c, int r) {
  const int w = scan.width;
  return scan.at(field, ((c % w) + w) % w, r) * 1e-3;
}

bool depth_step(double a, double b) { return a > 0 && b > 0 && std::abs(a - b) > std::max(0.3, 0.05 * std::max(a, b)); }

// The ideal ranges of the pixel's neighbours that lie across a depth step (the rows above and below
// in its column, the same row in the adjacent columns).
std::vector<double> partners(const Scan& ideal, int c, int r) {
  const double own = range_at(ideal, ChannelField::kRange, c, r);
  std::vector<double> out;
  const int neighbours[4][2] = {{0, -1}, {0, 1}, {-1, 0}, {1, 0}};
  for (const auto& [dc, dr] : neighbours) {
    if (r + dr < 0 || r + dr >= ideal.height) continue;
    const double other = range_at(ideal, ChannelField::kRange, c + dc, r + dr);
    if (depth_step(own, other)) out.push_back(other);
  }
  return out;
}

TEST(RecordMixedPixels, SecondReturnsLieAtDepthEdgesAtTheOtherSurfacesRange) {
  const auto ideal = decode_capture(record(table_profile("os1-64").string(), "ideal", 1, true));
  const auto mixed = decode_capture(record(profile_with_mixed_pixels().string(), "mixed", 5, false));
  const auto plain = decode_capture(record(table_profile("os1-64").string(), "plain", 2, false));
  ASSERT_FALSE(ideal.frames.empty());
  ASSERT_EQ(mixed.frames.size(), 5u);
  const Scan& truth = ideal.frames.begin()->second;

  size_t edge_pixels = 0;
  for (int c = 0; c < truth.width; ++c) {
    for (int r = 0; r < truth.height; ++r) edge_pixels += !partners(truth, c, r).empty();
  }
  size_t second = 0, second_off_edge = 0, second_not_a_surface = 0, flying = 0, flying_off_edge = 0;
  for (const auto& [frame_id, scan] : mixed.frames) {
    for (int c = 0; c < scan.width; ++c) {
      for (int r = 0; r < scan.height; ++r) {
        const double own = range_at(truth, ChannelField::kRange, c, r);
        const double first = range_at(scan, ChannelField::kRange, c, r);
        const double range2 = range_at(scan, ChannelField::kRange2, c, r);
        const std::vector<double> across = partners(truth, c, r);
        // A first return far from the pixel's own surface (beyond 8 sigma of os1-64's noise).
        if (first > 0 && own > 0 && std::abs(first - own) > 0.4) {
          ++flying;
          flying_off_edge += across.empty();
        }
        if (range2 <= 0) continue;
        ++second;
        if (across.empty()) {
          ++second_off_edge;
          continue;
        }
        // The second return is one of the two surfaces: the pixel's own or a partner's (+- noise).
        bool surface = std::abs(range2 - own) < 0.4;
        for (const double p : across) surface = surface || std::abs(range2 - p) < 0.4;
        second_not_a_surface += !surface;
      }
    }
  }
  std::printf(
      "edge pixels %zu per frame; over 5 frames: second returns %zu (%zu off edges, %zu not at a surface), "
      "first returns off their surface %zu (%zu off edges)\n",
      edge_pixels, second, second_off_edge, second_not_a_surface, flying, flying_off_edge);
  EXPECT_GT(edge_pixels, 500u) << "the hall's boards give edges";
  EXPECT_GT(second, 500u) << "second returns at the boards' edges";
  EXPECT_EQ(second_off_edge, 0u);
  EXPECT_EQ(second_not_a_surface, 0u);
  EXPECT_GT(flying, 0u) << "some edge pixels report the partner's surface first";
  EXPECT_EQ(flying_off_edge, 0u);

  size_t plain_second = 0;
  for (const auto& [frame_id, scan] : plain.frames) {
    for (int c = 0; c < scan.width; ++c) {
      for (int r = 0; r < scan.height; ++r) plain_second += range_at(scan, ChannelField::kRange2, c, r) > 0;
    }
  }
  EXPECT_EQ(plain_second, 0u) << "without mixed_pixels the profile has no second return";
}

}  // namespace

}  // namespace cli_record_mixed_pixels_test
