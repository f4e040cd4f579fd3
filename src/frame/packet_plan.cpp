#include "lidartwin/frame/packet_plan.h"

#include <array>
#include <cassert>

namespace lidartwin {

namespace {
// Whether packet [first, first + cpp) meets the inclusive window; a window with c0 > c1 wraps
// through m = 0 (6.4).
bool packet_meets_window(int first, int columns_per_packet, const std::array<int, 2>& window) {
  const int last = first + columns_per_packet - 1;
  const auto [c0, c1] = window;
  if (c0 <= c1) return first <= c1 && last >= c0;
  return last >= c0 || first <= c1;
}
}  // namespace

std::vector<int> packets_to_send(const LidarDataFormat& format) {
  const int cpp = format.columns_per_packet;
  assert(cpp > 0 && format.columns_per_frame % cpp == 0);
  std::vector<int> firsts;
  for (int first = 0; first < format.columns_per_frame; first += cpp) {
    if (packet_meets_window(first, cpp, format.column_window)) firsts.push_back(first);
  }
  return firsts;
}

}  // namespace lidartwin
