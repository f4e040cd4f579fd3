#pragma once
// Casting runs ahead of the send clock (protocol doc 1 item 12 needs packets on time, casting a
// frame takes milliseconds): a worker thread has the forward model render whole frames into a
// ring of `frames_ahead + 1` slots, publishing each packet as soon as its columns are encoded. The
// send clock only copies finished bytes to the socket, so it is never late because of ray casting.
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

namespace lidartwin::streamer_detail {

class RenderAhead {
 public:
  // model must outlive this. worker_nice: the worker's nice value (it also leaves any real-time
  // policy it inherited, so the send clock wins the CPU when a deadline comes).
  RenderAhead(const ForwardModel& model, int frames_ahead, int worker_nice);
  ~RenderAhead();  // stops the worker and joins it
  RenderAhead(const RenderAhead&) = delete;
  RenderAhead& operator=(const RenderAhead&) = delete;

  // The encoded packet `index` of `frame`, or empty if the worker has not finished it yet.
  std::span<const uint8_t> packet(uint64_t frame, size_t index) const;
  // The send clock is done with every frame up to `frame`: their slots are free, and the worker
  // skips (or abandons) any frame before frame + 1 that it has not rendered yet.
  void finished(uint64_t frame);
  // Time the worker spent rendering and encoding since the last call.
  uint64_t take_busy_ns() { return busy_ns_.exchange(0); }

 private:
  struct Slot {
    std::atomic<uint64_t> frame{UINT64_MAX};
    std::atomic<size_t> ready{0};  // packets [0, ready) are encoded
    EncodedFrame encoded;
  };

  void run();
  bool wait_for_room(uint64_t& frame);  // false when stopping
  void render_frame(uint64_t frame, Slot& slot);
  bool abandoned(uint64_t frame) const { return frame < next_needed_.load(std::memory_order_acquire); }

  const ForwardModel& model_;
  int worker_nice_ = 0;
  std::vector<std::pair<size_t, size_t>> chunks_;  // packet index ranges rendered in one call
  std::vector<std::unique_ptr<Slot>> slots_;
  std::atomic<uint64_t> busy_ns_{0};
  std::atomic<uint64_t> next_needed_{0};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;  // guarded by mutex_
  std::thread worker_;     // last member: started once everything it reads exists
};

}  // namespace lidartwin::streamer_detail
