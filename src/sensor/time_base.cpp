#include "lidartwin/sensor/time_base.h"

#include <chrono>

namespace lidartwin {

std::optional<TimestampMode> timestamp_mode_from_string(std::string_view text) {
  if (text == "TIME_FROM_INTERNAL_OSC") return TimestampMode::kInternalOsc;
  if (text == "TIME_FROM_SYNC_PULSE_IN") return TimestampMode::kSyncPulseIn;
  if (text == "TIME_FROM_PTP_1588") return TimestampMode::kPtp1588;
  return std::nullopt;
}

// std::chrono::steady_clock is CLOCK_MONOTONIC on Linux (libstdc++), the clock asio's steady
// timers pace the packets on.
int64_t TimeBase::steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

TimeBase TimeBase::from_host() {
  const int64_t wall_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  return TimeBase(wall_ns + kTaiMinusUtcNs - steady_now_ns());
}

int64_t TimeBase::offset_ns(TimestampMode mode) const {
  return mode == TimestampMode::kPtp1588 ? tai_minus_steady_ns_ : 0;
}

}  // namespace lidartwin
