#pragma once
// Where one streaming session's frames sit on the three clocks that matter: the host's steady clock
// (when to send), the sensor's timestamp clock (what packets carry, protocol doc 6.3) and the
// trajectory's time (where the sensor is).
#include <chrono>
#include <cstdint>

#include "lidartwin/streamer/packet_schedule.h"

namespace lidartwin::streamer_detail {

inline int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

struct SessionTiming {
  ColumnClock clock;
  int64_t start_steady_ns = 0;          // frame 0 starts here
  int64_t timestamp_offset_ns = 0;      // column timestamp = steady ns + this
  double trajectory_start_s = 0.0;      // trajectory time at frame 0's start

  int64_t column_steady_ns(uint64_t frame, int measurement_id) const {
    return start_steady_ns + static_cast<int64_t>(clock.column_time_ns(frame, measurement_id));
  }
  uint64_t column_timestamp_ns(uint64_t frame, int measurement_id) const {
    return static_cast<uint64_t>(column_steady_ns(frame, measurement_id) + timestamp_offset_ns);
  }
  double frame_trajectory_time_s(uint64_t frame) const {
    return trajectory_start_s + static_cast<double>(clock.frame_start_ns(frame)) * 1e-9;
  }
  // Offset of an instant on the steady clock into the trajectory's time.
  double trajectory_time_s(int64_t steady_ns) const {
    return trajectory_start_s + static_cast<double>(steady_ns - start_steady_ns) * 1e-9;
  }
};

}  // namespace lidartwin::streamer_detail
