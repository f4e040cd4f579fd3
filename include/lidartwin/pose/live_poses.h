#pragma once
// Poses that arrive while the sensor runs (a HIL rig's vehicle simulator or motion platform): a
// PoseSource that interpolates between the poses received, extrapolates a bounded time past the
// newest, and says through span() what it cannot answer for, so that the forward model leaves those
// columns unobserved (or the streamer withholds them) instead of casting from a made-up pose.
// docs/live-poses.md describes the messages, the clocks and the timeout policies for users.
#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lidartwin/pose/pose_message.h"
#include "lidartwin/pose/pose_source.h"

namespace lidartwin {

// Which clock a message's time_ns is on.
enum class PoseClock {
  kSender,      // the sender's own clock: mapped to the host's by the smallest transit seen
  kMonotonic,   // this host's CLOCK_MONOTONIC (the clock TIME_FROM_INTERNAL_OSC packets carry)
  kRealtime,    // CLOCK_REALTIME (UTC ns; PTP- or NTP-disciplined hosts)
  kTai,         // TAI ns, CLOCK_REALTIME + 37 s (what TIME_FROM_PTP_1588 packets carry)
  kSimulation,  // lock-step: the simulation's own time, which the sensor's clock follows
};
// What happens to columns later than the newest pose plus the extrapolation bound.
enum class PoseTimeout {
  kHold,     // cast from the pose extrapolation reached: the stream goes on, frozen
  kInvalid,  // sent with status 0 and no returns, as a sensor with no data for them
  kStandby,  // packets with no column to cast are not sent, until poses return
};
std::optional<PoseClock> parse_pose_clock(std::string_view name);      // "sender", "monotonic", ...
std::optional<PoseTimeout> parse_pose_timeout(std::string_view name);  // "hold", "invalid", "standby"
const char* to_string(PoseClock clock);
const char* to_string(PoseTimeout timeout);

// The host's steady clock (CLOCK_MONOTONIC, std::chrono::steady_clock), in ns: what arrival times
// and the rig's epoch are read on.
int64_t host_steady_ns();

struct LivePoseOptions {
  PoseClock clock = PoseClock::kSender;
  double max_extrapolation_s = 0.1;  // past the newest pose, with its velocity (given or differenced)
  PoseTimeout timeout = PoseTimeout::kInvalid;
  double history_s = 10.0;  // poses older than this behind the newest are forgotten
};

struct LivePoseStats {
  uint64_t accepted = 0;
  std::array<uint64_t, static_cast<size_t>(PoseRejection::kCount)> rejected{};
  uint64_t lost = 0;  // gaps in the sequence numbers of accepted messages
  std::optional<PoseMessage> newest;
  int64_t newest_arrival_steady_ns = 0;
  int64_t clock_offset_ns = 0;  // host steady clock minus the message clock
  uint64_t rejected_total() const;
};

class LivePoses final : public PoseSource {
 public:
  // Pose-source time is seconds since epoch_steady_ns on the host's steady clock (the rig's time
  // zero), so the forward model's column times need no knowledge of the message clock.
  LivePoses(LivePoseOptions options, int64_t epoch_steady_ns);

  // Any thread. Throws PoseRejected (and counts it) for a message whose time is not after the
  // newest accepted one; the message was already checked by its decoder.
  void receive(const PoseMessage& message, int64_t arrival_steady_ns);
  // Counts a message its decoder refused.
  void count_rejection(PoseRejection reason);

  Pose at(double time_s) const override;
  PoseSpan span() const override;
  double start_s() const override { return 0.0; }
  PoseFreshness freshness() const override;

  LivePoseStats stats() const;
  const LivePoseOptions& options() const { return options_; }

  // Called with every accepted message, after it was added, on the thread that received it (the
  // lock-step streamers advance their clocks with it). Returns an id for unsubscribe().
  using Listener = std::function<void(const PoseMessage& message)>;
  int subscribe(Listener listener);
  void unsubscribe(int id);
  // Pose-source time of a steady-clock instant, and back.
  double source_time_s(int64_t steady_ns) const;
  int64_t steady_ns(double source_time_s) const;

 private:
  struct Sample {
    int64_t time_ns;  // message clock
    PoseMessage message;
  };
  void add(const PoseMessage& message, int64_t arrival_steady_ns);  // throws PoseRejected
  int64_t offset_ns_locked(int64_t arrival_steady_ns, int64_t message_ns);
  double sample_time_s(const Sample& sample) const;  // pose-source time; mutex_ held
  Pose extrapolate(double ahead_s) const;            // from the newest sample; mutex_ held

  LivePoseOptions options_;
  int64_t epoch_steady_ns_;
  mutable std::mutex mutex_;
  std::deque<Sample> samples_;  // by time, guarded by mutex_
  LivePoseStats stats_;         // guarded by mutex_
  std::optional<int64_t> sender_offset_ns_;
  mutable std::mutex listeners_mutex_;
  std::vector<std::pair<int, Listener>> listeners_;  // guarded by listeners_mutex_
  int next_listener_ = 1;
};

}  // namespace lidartwin
