#pragma once
// How far apart the send clock's coalesced wake-ups are (StreamerOptions::coalesce_us), looked at
// once a second. Coalescing begins at the base window; while casting still falls behind (a render
// stall since the last look) the window doubles at each look, up to kWidestCoalescing times the
// base (at most kWidestCoalescingNs), and once it keeps up halves back towards the base. On a host
// with far more daemons than cores each wake-up saved is CPU given to casting: 32 daemons on 2
// cores woke 10,000 times a second at 2 ms and rendered 5.5 M pixels/s; widening, 13 M pixels/s,
// what a rig renders there (docs/rig.md).
#include <algorithm>
#include <cstdint>

namespace lidartwin {

inline constexpr int64_t kWidestCoalescing = 8;
// And never wider than this: packets held back stay well within the shortest frame (50 ms at
// 20 Hz), past which the send clock skips a packet rather than send it.
inline constexpr int64_t kWidestCoalescingNs = 20'000'000;

// The window after a look: `window_ns` the one before (0: not coalescing), `coalesce` whether the
// send clock coalesces now (a contended host where casting fell behind, or asked to), `stalled`
// whether casting fell behind since the last look. 0 when not coalescing.
constexpr int64_t next_coalescing_window(int64_t window_ns, int64_t base_ns, bool coalesce, bool stalled) {
  if (!coalesce || base_ns <= 0) return 0;
  if (window_ns <= 0) return base_ns;
  const int64_t widest = std::max(base_ns, std::min(kWidestCoalescing * base_ns, kWidestCoalescingNs));
  return stalled ? std::min(2 * window_ns, widest) : std::max(window_ns / 2, base_ns);
}

}  // namespace lidartwin
