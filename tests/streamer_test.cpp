// The send clock's coalescing window as the streamer looks at it once a second
// (lidartwin/streamer/coalescing_window.h): what a daemon on an overloaded host does to its wake-ups.
#include <gtest/gtest.h>

#include "lidartwin/streamer/coalescing_window.h"

namespace lidartwin {
namespace {

constexpr int64_t kBase = 2'000'000;  // --coalesce-us 2000

// One look a second: `stalls` says, for each second, whether casting fell behind in it.
std::vector<int64_t> windows_over(const std::vector<bool>& stalls, bool coalesce = true) {
  std::vector<int64_t> windows;
  int64_t window = 0;
  for (const bool stalled : stalls)
    windows.push_back(window = next_coalescing_window(window, kBase, coalesce, stalled));
  return windows;
}

TEST(CoalescingWindow, WidensWhileCastingStillFallsBehindUpToEightTimesTheBase) {
  EXPECT_EQ(windows_over({true, true, true, true, true, true}),
            (std::vector<int64_t>{kBase, 2 * kBase, 4 * kBase, 8 * kBase, 8 * kBase, 8 * kBase}));
}

// --coalesce-us 10000 (its largest) widens to 20 ms, not 80: held packets stay well within a
// 20 Hz frame (50 ms), past which the send clock would skip them.
TEST(CoalescingWindow, NeverWidensPast20Ms) {
  int64_t window = 0;
  for (int look = 0; look < 5; ++look) window = next_coalescing_window(window, 10'000'000, true, true);
  EXPECT_EQ(window, 20'000'000);
}

TEST(CoalescingWindow, NarrowsBackToTheBaseOnceCastingKeepsUp) {
  EXPECT_EQ(
      windows_over({true, true, true, true, false, false, false, false, true}),
      (std::vector<int64_t>{kBase, 2 * kBase, 4 * kBase, 8 * kBase, 4 * kBase, 2 * kBase, kBase, kBase, 2 * kBase}));
}

TEST(CoalescingWindow, EndsWhenTheHostIsFreeOrCoalescingIsOff) {
  EXPECT_EQ(windows_over({true, true}, false), (std::vector<int64_t>{0, 0}));
  EXPECT_EQ(next_coalescing_window(8 * kBase, kBase, false, true), 0);  // the host is free again
  EXPECT_EQ(next_coalescing_window(0, 0, true, true), 0);               // --coalesce-us 0
}

}  // namespace
}  // namespace lidartwin
