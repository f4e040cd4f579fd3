// The way back from a point to the pixel that saw it, on a real capture's beams: every return of
// the OS-1-128 sample projects back to its own pixel (or, for the few whose beams a neighbour's
// passes as close, to an adjacent one).
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <utility>

#include <gtest/gtest.h>

#include "../../src/analysis/capture_points.h"
#include "lidartwin/analysis/measured_capture.h"

namespace lidartwin {
namespace {

TEST(BeamProjector, EveryReturnOfARealCaptureProjectsBackToItsPixel) {
  const std::string dir = std::string(LIDARTWIN_SOURCE_DIR) + "/tests/data/ouster-samples/";
  const MeasuredCapture capture =
      read_capture(dir + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap", dir + "OS-1-128_v2.3.0_1024x10.json", 1);
  const std::vector<analysis_detail::FramePoints> frames = analysis_detail::capture_points(capture);
  ASSERT_EQ(frames.size(), 1u);
  const analysis_detail::BeamProjector projector(capture.metadata);
  const analysis_detail::FramePoints& f = frames.front();
  size_t returns = 0, exact = 0, adjacent = 0;
  for (int m = 0; m < f.width; ++m) {
    for (int r = 0; r < f.height; ++r) {
      const size_t i = f.index(m, r);
      if (!f.returned(i) || f.range_m[i] < 1.0f) continue;
      ++returns;
      const auto pixel = projector.project(f.sensor[i]);
      const int dm = std::min(std::abs(pixel.m - m), f.width - std::abs(pixel.m - m));
      exact += pixel.m == m && pixel.r == r;
      adjacent += dm <= 1 && std::abs(pixel.r - r) <= 1;
    }
  }
  ASSERT_GT(returns, 50000u);
  EXPECT_GT(static_cast<double>(exact), 0.95 * static_cast<double>(returns));
  EXPECT_EQ(adjacent, returns);
}

// The projection's own atan2 against libm's, over every octant, the axes and the origin.
TEST(BeamProjector, ItsAtan2AgreesWithLibmToTwoHundredthsOfAMicroradian) {
  double worst = 0.0;
  for (int i = 0; i < 100'000; ++i) {
    const double angle = -3.2 + 6.4 * i / 100'000.0;
    for (const double radius : {1e-3, 1.0, 250.0}) {
      const double y = radius * std::sin(angle), x = radius * std::cos(angle);
      worst = std::max(worst, std::abs(analysis_detail::projection_atan2(y, x) - std::atan2(y, x)));
    }
  }
  EXPECT_LT(worst, 2e-8);
  for (const auto& [y, x] : {std::pair{0.0, 1.0}, {1.0, 0.0}, {0.0, -1.0}, {-1.0, 0.0}, {0.0, 0.0}, {2.0, 2.0}}) {
    EXPECT_NEAR(analysis_detail::projection_atan2(y, x), std::atan2(y, x), 2e-8) << y << ", " << x;
  }
}

}  // namespace
}  // namespace lidartwin
