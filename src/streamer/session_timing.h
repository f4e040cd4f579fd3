#pragma once
// Where one streaming session sits on the host's steady clock: frame 0 starts at start_steady_ns,
// and everything after follows the sensor's clock (frame/sensor_clock.h), whose origin carries
// the timestamp offset of the config's timestamp_mode and the pose source's time at that instant.
#include <chrono>
#include <cstdint>

#include "lidartwin/frame/sensor_clock.h"

namespace lidartwin::streamer_detail {

inline int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

struct SessionTiming {
  int64_t start_steady_ns = 0;  // frame 0's column 0 is observed here
  SensorClock clock;

  // The steady-clock instant of a time given relative to the sensor clock's origin.
  int64_t steady_ns(uint64_t since_origin_ns) const { return start_steady_ns + static_cast<int64_t>(since_origin_ns); }
  // The steady-clock instant of a sensor timestamp (a packet's deadline is its last column's).
  int64_t steady_ns_of_timestamp(uint64_t timestamp_ns) const { return steady_ns(timestamp_ns - clock.origin_ns); }
};

}  // namespace lidartwin::streamer_detail
