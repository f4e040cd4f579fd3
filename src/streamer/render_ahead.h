#pragma once
// Casting runs ahead of the send clock (protocol doc 1 item 12 needs packets on time, casting a
// frame takes milliseconds): a worker thread renders and encodes whole frames into a ring of
// `frames_ahead + 1` slots, publishing each packet as soon as its columns are done. The send clock
// only copies finished bytes to the socket, so it is never late because of ray casting.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <utility>
#include <vector>

#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/render/frame_renderer.h"
#include "streamer/session_timing.h"

namespace lidartwin::streamer_detail {

class RenderAhead {
 public:
  using RendererFactory = std::function<std::unique_ptr<FrameRenderer>()>;
  // header carries init_id and prod_sn; frame_id is set per frame. trajectory must outlive this.
  // The renderer is built on the worker thread after it lowers its priority, so the renderer's own
  // pool inherits that priority and the send clock wins the CPU when a deadline comes.
  // worker_nice: the worker's nice value (it also leaves any real-time policy it inherited).
  RenderAhead(RendererFactory make_renderer, PacketFormat format, const Trajectory& trajectory,
              SessionTiming timing, PacketHeader header, int frames_ahead, int worker_nice);
  ~RenderAhead();  // stops the worker and joins it
  RenderAhead(const RenderAhead&) = delete;
  RenderAhead& operator=(const RenderAhead&) = delete;

  // First measurement ids of the packets each frame sends (packets_to_send), in send order.
  const std::vector<int>& packet_columns() const { return firsts_; }
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
    Scan scan;
    std::vector<uint8_t> bytes;    // packet_columns().size() packets back to back
  };

  void run();
  bool wait_for_room(uint64_t& frame);  // false when stopping
  void render_frame(uint64_t frame, Slot& slot);
  void stamp_columns(uint64_t frame, int first, int last, Scan& scan) const;
  bool abandoned(uint64_t frame) const { return frame < next_needed_.load(std::memory_order_acquire); }

  RendererFactory make_renderer_;
  std::unique_ptr<FrameRenderer> renderer_;  // built and used by the worker only
  PacketFormat format_;
  const Trajectory& trajectory_;
  SessionTiming timing_;
  PacketHeader header_;
  int worker_nice_ = 0;
  std::vector<int> firsts_;
  std::vector<std::pair<size_t, size_t>> chunks_;  // packet index ranges cast in one render call
  std::vector<std::unique_ptr<Slot>> slots_;
  std::atomic<uint64_t> busy_ns_{0};
  std::atomic<uint64_t> next_needed_{0};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;  // guarded by mutex_
  std::thread worker_;     // last member: started once everything it reads exists
};

}  // namespace lidartwin::streamer_detail
