#pragma once
// The sensor's clocks on the host (protocol doc 6.3), one mapping from the host's steady clock
// (CLOCK_MONOTONIC) to each timestamp_mode's time. Column and IMU timestamps, GET time/sensor,
// time/system and telemetry's timestamp_ns all read it, so a client sees one clock everywhere, as
// on a real sensor; the sensors of a rig share one, so their timestamps agree as on a vehicle
// whose sensors all follow one PTP grandmaster.
//
// - TIME_FROM_INTERNAL_OSC counts from the sensor's power-on; a virtual sensor powers on with its
//   host, so this is CLOCK_MONOTONIC itself: a receiver on the same host measures a packet's
//   lateness as (its receive CLOCK_MONOTONIC - its timestamp), and live poses stamped on
//   CLOCK_MONOTONIC (--pose-clock monotonic) are on the packets' clock.
// - TIME_FROM_SYNC_PULSE_IN is a counter the pulse input resets; a virtual sensor has no pulse
//   input, so its counter runs free, as the internal oscillator does.
// - TIME_FROM_PTP_1588 is TAI: CLOCK_REALTIME + 37 s, read once when the time base is made, so every
//   timestamp is the same fixed offset from the steady clock (a step of the host's wall clock
//   afterwards does not make the sensor's time jump; a PTP-disciplined host slews instead).
#include <cstdint>
#include <optional>
#include <string_view>

namespace lidartwin {

enum class TimestampMode { kInternalOsc, kSyncPulseIn, kPtp1588 };
// "TIME_FROM_INTERNAL_OSC", ... as in the config (protocol doc 2.6).
std::optional<TimestampMode> timestamp_mode_from_string(std::string_view text);

inline constexpr int64_t kTaiMinusUtcNs = 37'000'000'000;  // leap seconds since 2017

class TimeBase {
 public:
  // TAI's offset from the host's steady clock, read from CLOCK_REALTIME now.
  static TimeBase from_host();
  explicit TimeBase(int64_t tai_minus_steady_ns) : tai_minus_steady_ns_(tai_minus_steady_ns) {}

  static int64_t steady_now_ns();  // CLOCK_MONOTONIC
  // What the mode's clock reads at a steady-clock instant, in ns.
  int64_t offset_ns(TimestampMode mode) const;
  int64_t time_ns(TimestampMode mode, int64_t steady_ns) const { return steady_ns + offset_ns(mode); }
  int64_t now_ns(TimestampMode mode) const { return time_ns(mode, steady_now_ns()); }

 private:
  int64_t tai_minus_steady_ns_;
};

}  // namespace lidartwin
