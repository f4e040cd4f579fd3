#pragma once
// Casting runs ahead of the send clock (protocol doc 1 item 12 needs packets on time, casting a
// frame takes milliseconds): a worker thread has the forward model render whole frames into a
// ring of `frames_ahead + 1` slots, publishing each packet as soon as its columns are encoded. The
// send clock only copies finished bytes to the socket, so it is never late because of ray casting.
// With live poses, running ahead makes poses stale: a paced worker casts each packet only
// cast_ahead before it is due, so the newest pose received reaches the next packet.
// A worker that has fallen behind the send clock (a host with more work than cores) skips the
// packets it can no longer finish in time: they go out blank either way (render stalls), and
// casting them would make every later packet late too, so that a short shortage of CPU would
// stall the stream for good. Skipping keeps the stalls in proportion to the CPU that was missing.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <utility>
#include <vector>

#include "lidartwin/frame/forward_model.h"
#include "streamer/session_timing.h"

namespace lidartwin::streamer_detail {

class RenderAhead {
 public:
  struct Options {
    int frames_ahead = 2;
    // The worker's nice value (it also leaves any real-time policy it inherited, so the send clock
    // wins the CPU when a deadline comes).
    int worker_nice = 0;
    // > 0: cast each packet no earlier than this before its deadline, one packet at a time.
    int64_t cast_ahead_ns = 0;
  };
  // model must outlive this; timing places its packets on the steady clock.
  RenderAhead(const ForwardModel& model, const SessionTiming& timing, Options options);
  ~RenderAhead();  // stops the worker and joins it
  RenderAhead(const RenderAhead&) = delete;
  RenderAhead& operator=(const RenderAhead&) = delete;

  // The encoded packet `index` of `frame`, or empty if the worker has not finished it yet.
  std::span<const uint8_t> packet(uint64_t frame, size_t index) const;
  // The send clock is done with every frame up to `frame`: their slots are free, and the worker
  // skips (or abandons) any frame before frame + 1 that it has not rendered yet.
  void finished(uint64_t frame);
  // The frame a finished packet was rendered into (its columns' poses and timestamps).
  const EncodedFrame& encoded(uint64_t frame) const { return slots_[frame % slots_.size()]->encoded; }
  // Whether a finished packet has any observed column (false: every column lacked a pose).
  bool observed(uint64_t frame, size_t index) const;
  // What the pose source had heard when a finished packet (packet() not empty) was cast.
  PoseFreshness freshness(uint64_t frame, size_t index) const;
  // Time the worker spent rendering and encoding since the last call.
  uint64_t take_busy_ns() { return busy_ns_.exchange(0); }
  // Columns in the window that went out unobserved for want of a pose, since the last call.
  uint64_t take_unposed_columns() { return unposed_columns_.exchange(0); }

 private:
  struct Slot {
    explicit Slot(size_t packets);
    // Per packet: the frame whose bytes it holds, stored (release) once they are encoded.
    std::vector<std::atomic<uint64_t>> packet_frame;
    EncodedFrame encoded;
    std::vector<PoseFreshness> freshness;  // per packet
  };

  void run();
  bool wait_for_room(uint64_t& frame);  // false when stopping
  bool wait_until(int64_t steady_ns);   // false when stopping
  void render_frame(uint64_t frame, Slot& slot);
  int64_t deadline_ns(uint64_t frame, size_t index) const;
  size_t first_in_time(uint64_t frame, size_t begin, size_t end) const;
  bool abandoned(uint64_t frame) const { return frame < next_needed_.load(std::memory_order_acquire); }

  const ForwardModel& model_;
  SessionTiming timing_;
  Options options_;
  std::vector<std::pair<size_t, size_t>> chunks_;  // packet index ranges rendered in one call
  std::vector<std::unique_ptr<Slot>> slots_;
  std::atomic<uint64_t> busy_ns_{0};
  std::atomic<uint64_t> unposed_columns_{0};
  static constexpr uint64_t kStopping = UINT64_MAX;  // next_needed_ when the worker must stop
  std::atomic<uint64_t> next_needed_{0};
  // How long a packet takes to cast, smoothed over the chunks cast (worker thread only), and an
  // eighth less for each chunk skipped whole: one slow chunk (the worker preempted mid-cast) must
  // not make it skip every packet after, as the last chunk's time alone did at a 1 ms cast-ahead
  // (72 % of packets blank where 1 % had been late). Halving instead recovered faster but, on a
  // host with too little CPU, cast more packets too late to be sent (16 daemons: 81-90 % stalls
  // against 64-73 %; an eighth: 72-81 %).
  int64_t packet_ns_ = 0;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;  // guarded by mutex_
  std::thread worker_;     // last member: started once everything it reads exists
};

}  // namespace lidartwin::streamer_detail
