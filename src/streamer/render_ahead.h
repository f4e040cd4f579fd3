#pragma once
// Casting runs ahead of the send clock (protocol doc 1 item 12 needs packets on time, casting a
// frame takes milliseconds): a worker thread has the forward model render whole frames into a
// ring of `frames_ahead + 1` slots, publishing each packet as soon as its columns are encoded. The
// send clock only copies finished bytes to the socket, so it is never late because of ray casting.
// With live poses, running ahead makes poses stale: a paced worker casts each packet only
// cast_ahead before it is due, and when a pose arrives after that, casts it once more with the new
// pose into a second copy, if there is still time before it is due (packets cast far ahead wait
// until they are due within about a packet's period). The sender takes whichever copy was published
// last; a packet is cast at most twice per frame, so neither copy is ever written while the sender
// may read it, without a lock. The latency from a pose to the first packet sent with it is then the
// wait for the next packet that can still be cast again (at 1024x10 packets are 1.56 ms apart), not
// that plus cast_ahead.
// A worker that has fallen behind the send clock (a host with more work than cores) skips the
// packets it can no longer finish in time: they go out blank either way (render stalls), and
// casting them would make every later packet late too, so that a short shortage of CPU would
// stall the stream for good. Skipping keeps the stalls in proportion to the CPU that was missing.
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <thread>
#include <utility>
#include <vector>

#include "lidartwin/frame/forward_model.h"
#include "streamer/pose_news.h"
#include "streamer/session_timing.h"

namespace lidartwin::streamer_detail {

class RenderAhead {
 public:
  struct Options {
    int frames_ahead = 2;
    // The worker's nice value (it also leaves any real-time policy it inherited, so the send clock
    // wins the CPU when a deadline comes).
    int worker_nice = 0;
    // > 0 (paced): cast each packet first this long before its deadline, one packet at a time, and
    // again when a pose arrives before it is due (the file comment).
    int64_t cast_ahead_ns = 0;
  };
  // model must outlive this; timing places its packets on the steady clock. news (may be null; must
  // outlive this) wakes a paced worker when a pose arrives.
  RenderAhead(const ForwardModel& model, const SessionTiming& timing, Options options, PoseNews* news);
  ~RenderAhead();  // stops the worker and joins it
  RenderAhead(const RenderAhead&) = delete;
  RenderAhead& operator=(const RenderAhead&) = delete;

  // A packet the worker finished: its bytes, the frame it was rendered into (its columns' poses and
  // timestamps) and what the pose source had heard when it was cast, all of one copy.
  struct Ready {
    std::span<const uint8_t> bytes;
    const EncodedFrame* encoded = nullptr;
    PoseFreshness freshness;
  };
  // Packet `index` of `frame` as last published, or nullopt if the worker has not finished it yet.
  std::optional<Ready> ready(uint64_t frame, size_t index) const;
  // The send clock is done with every frame up to `frame`: their slots are free, and the worker
  // skips (or abandons) any frame before frame + 1 that it has not rendered yet.
  void finished(uint64_t frame);
  // Time the worker spent rendering and encoding since the last call.
  uint64_t take_busy_ns() { return busy_ns_.exchange(0); }
  // Columns in the window that went out unobserved for want of a pose, since the last call.
  uint64_t take_unposed_columns() { return unposed_columns_.exchange(0); }
  // Packets cast a second time because a pose arrived after their first cast, since the last call.
  uint64_t take_recasts() { return recasts_.exchange(0); }

 private:
  struct Slot {
    Slot(size_t packets, size_t copy_count);
    // Per packet: frame << 1 | the copy holding its bytes, stored (release) once they are encoded.
    std::vector<std::atomic<uint64_t>> published;
    std::vector<EncodedFrame> copies;                   // one, or two when paced
    std::vector<std::vector<PoseFreshness>> freshness;  // per copy, per packet
  };
  struct Position {
    uint64_t frame = 0;
    size_t index = 0;
  };

  void run();
  void run_paced();
  bool wait_for_room(uint64_t& frame);  // false when stopping
  // Until steady_ns, casting again what a pose arriving meanwhile makes stale; false when stopping.
  bool wait_recasting(int64_t steady_ns, std::vector<Position>& cast_once);
  int64_t recast(std::vector<Position>& cast_once, bool news);
  void render_frame(uint64_t frame);
  // Casts packets [begin, end) of frame into copy `copy` of its slot and publishes them.
  void cast(uint64_t frame, size_t begin, size_t end, size_t copy);
  int64_t deadline_ns(uint64_t frame, size_t index) const;
  size_t first_in_time(uint64_t frame, size_t begin, size_t end) const;
  bool abandoned(uint64_t frame) const { return frame < next_needed_.load(std::memory_order_acquire); }
  Slot& slot(uint64_t frame) const { return *slots_[frame % slots_.size()]; }

  const ForwardModel& model_;
  SessionTiming timing_;
  Options options_;
  std::vector<std::pair<size_t, size_t>> chunks_;  // packet index ranges rendered in one call
  int64_t recast_horizon_ns_;                      // paced: packets due within this may be cast again
  std::vector<std::unique_ptr<Slot>> slots_;
  std::atomic<uint64_t> busy_ns_{0};
  std::atomic<uint64_t> unposed_columns_{0};
  std::atomic<uint64_t> recasts_{0};
  static constexpr uint64_t kStopping = UINT64_MAX;  // next_needed_ when the worker must stop
  std::atomic<uint64_t> next_needed_{0};
  // How long a packet takes to cast, smoothed over the chunks cast (worker thread only), and an
  // eighth less for each chunk skipped whole: one slow chunk (the worker preempted mid-cast) must
  // not make it skip every packet after, as the last chunk's time alone did at a 1 ms cast-ahead
  // (72 % of packets blank where 1 % had been late). Halving instead recovered faster but, on a
  // host with too little CPU, cast more packets too late to be sent (16 daemons: 81-90 % stalls
  // against 64-73 %; an eighth: 72-81 %).
  int64_t packet_ns_ = 0;
  uint64_t news_handled_ = 0;  // PoseNews::count() when the worker last looked (worker thread only)
  PoseNews own_news_;          // waited on when no news is given (nothing ever arrives)
  PoseNews& news_;
  std::atomic<bool> stopping_{false};
  std::thread worker_;  // last member: started once everything it reads exists
};

}  // namespace lidartwin::streamer_detail
