#include "streamer/render_ahead.h"

#include <algorithm>
#include <chrono>

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include "lidartwin/streamer/packet_schedule.h"

namespace lidartwin::streamer_detail {

namespace {
// Columns cast per render call: small enough that the first packets of a frame are ready long
// before the frame is done, large enough to keep the renderer's pool busy.
constexpr int kColumnsPerChunk = 128;
constexpr std::chrono::milliseconds kRecheck{2};

// Threads inherit the scheduling policy of their creator: the io thread may run the send clock as
// SCHED_FIFO, which the worker and the renderer's pool (created from the worker) must not.
void lower_priority(int nice) {
  const sched_param normal{};
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice);  // per thread on Linux
}

// Runs of consecutive packets (a wrapping window has two), cut into chunks.
std::vector<std::pair<size_t, size_t>> plan_chunks(const std::vector<int>& firsts, int columns_per_packet) {
  const size_t max_packets = static_cast<size_t>(std::max(1, kColumnsPerChunk / columns_per_packet));
  std::vector<std::pair<size_t, size_t>> chunks;
  size_t begin = 0;
  for (size_t i = 1; i <= firsts.size(); ++i) {
    const bool run_ends = i == firsts.size() || firsts[i] != firsts[i - 1] + columns_per_packet;
    if (run_ends || i - begin == max_packets) {
      chunks.emplace_back(begin, i);
      begin = i;
    }
  }
  return chunks;
}
}  // namespace

RenderAhead::RenderAhead(RendererFactory make_renderer, PacketFormat format, const Trajectory& trajectory,
                         SessionTiming timing, PacketHeader header, int frames_ahead, int worker_nice)
    : make_renderer_(std::move(make_renderer)),
      format_(std::move(format)),
      trajectory_(trajectory),
      timing_(timing),
      header_(header),
      worker_nice_(worker_nice),
      firsts_(packets_to_send(format_.format())),
      chunks_(plan_chunks(firsts_, format_.format().columns_per_packet)) {
  for (int i = 0; i <= std::max(1, frames_ahead); ++i) {
    auto slot = std::make_unique<Slot>();
    slot->scan = Scan(format_.format());
    slot->bytes.resize(firsts_.size() * format_.lidar_packet_size());
    slots_.push_back(std::move(slot));
  }
  worker_ = std::thread([this] { run(); });
}

RenderAhead::~RenderAhead() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  next_needed_.store(UINT64_MAX, std::memory_order_release);  // abandon the frame in progress
  wake_.notify_all();
  worker_.join();
}

std::span<const uint8_t> RenderAhead::packet(uint64_t frame, size_t index) const {
  const Slot& slot = *slots_[frame % slots_.size()];
  if (slot.frame.load(std::memory_order_acquire) != frame) return {};
  if (slot.ready.load(std::memory_order_acquire) <= index) return {};
  const size_t size = format_.lidar_packet_size();
  return {slot.bytes.data() + index * size, size};
}

// Called by the send clock, which must never wait for the worker: no lock is taken (a lock held by
// a preempted worker would stall a real-time sender). A wake-up lost between the worker's check
// and its wait costs at most kRecheck, well within the frames it renders ahead.
void RenderAhead::finished(uint64_t frame) {
  next_needed_.store(frame + 1, std::memory_order_release);
  wake_.notify_all();
}

bool RenderAhead::wait_for_room(uint64_t& frame) {
  std::unique_lock lock(mutex_);
  // A frame's slot is free once the sender finished the frame that used it slots_.size() ago.
  const auto room = [&] {
    frame = std::max(frame, next_needed_.load(std::memory_order_acquire));
    return stopping_ || frame < next_needed_.load(std::memory_order_acquire) + slots_.size();
  };
  while (!room()) wake_.wait_for(lock, kRecheck);
  return !stopping_;
}

void RenderAhead::run() {
  uint64_t frame = 0;
  try {
    lower_priority(worker_nice_);
    renderer_ = make_renderer_();
    while (wait_for_room(frame)) {
      const int64_t began = steady_now_ns();
      render_frame(frame, *slots_[frame % slots_.size()]);
      busy_ns_.fetch_add(static_cast<uint64_t>(steady_now_ns() - began));
      ++frame;
    }
  } catch (const std::exception& e) {
    // A bug, not bad input (the config was validated before the reinit): the send clock keeps
    // going and reports every packet it cannot fill as a render stall.
    spdlog::error("streamer: rendering stopped: {}", e.what());
  }
}

void RenderAhead::render_frame(uint64_t frame, Slot& slot) {
  slot.ready.store(0, std::memory_order_relaxed);
  slot.frame.store(frame, std::memory_order_release);
  PacketHeader header = header_;
  header.frame_id = frame_id_of(frame, format_.format());
  const double frame_start_s = timing_.frame_trajectory_time_s(frame);
  const int cpp = format_.format().columns_per_packet;
  const size_t size = format_.lidar_packet_size();
  for (const auto& [begin, end] : chunks_) {
    if (abandoned(frame)) return;
    const int first = firsts_[begin];
    const int last = firsts_[end - 1] + cpp;
    renderer_->render(frame, frame_start_s, trajectory_, first, last, slot.scan);
    stamp_columns(frame, first, last, slot.scan);
    for (size_t i = begin; i < end; ++i) {
      format_.encode(header, slot.scan, firsts_[i], std::span<uint8_t>(slot.bytes.data() + i * size, size));
    }
    slot.ready.store(end, std::memory_order_release);
  }
}

// Column timestamps in the session's sensor clock (6.3) and status from the window (6.4): what
// the packets say about time and validity is the streamer's business, not the renderer's.
void RenderAhead::stamp_columns(uint64_t frame, int first, int last, Scan& scan) const {
  const auto& format = format_.format();
  const uint32_t valid = format.udp_profile_lidar == UdpProfileLidar::kLegacy ? 0xFFFF'FFFFu : 1u;
  for (int m = first; m < last; ++m) {
    const auto column = static_cast<size_t>(m);
    scan.timestamp_ns[column] = timing_.column_timestamp_ns(frame, m);
    scan.status[column] = column_in_window(format.column_window, m) ? valid : 0u;
  }
}

}  // namespace lidartwin::streamer_detail
