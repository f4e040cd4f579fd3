#include "streamer/render_ahead.h"

#include <algorithm>
#include <chrono>

#include <spdlog/spdlog.h>

#include "lidartwin/frame/worker_pool.h"
#include "streamer/session_timing.h"

namespace lidartwin::streamer_detail {

namespace {
// Columns rendered per call: small enough that the first packets of a frame are ready long before
// the frame is done, large enough to keep the worker pool busy.
constexpr int kColumnsPerChunk = 128;
constexpr std::chrono::milliseconds kRecheck{2};

std::vector<std::pair<size_t, size_t>> plan_chunks(size_t packets, int columns_per_packet, bool paced) {
  const size_t per_chunk = paced ? 1 : static_cast<size_t>(std::max(1, kColumnsPerChunk / columns_per_packet));
  std::vector<std::pair<size_t, size_t>> chunks;
  for (size_t begin = 0; begin < packets; begin += per_chunk)
    chunks.emplace_back(begin, std::min(packets, begin + per_chunk));
  return chunks;
}
}  // namespace

RenderAhead::RenderAhead(const ForwardModel& model, const SessionTiming& timing, Options options)
    : model_(model),
      timing_(timing),
      options_(options),
      chunks_(
          plan_chunks(model.packet_columns().size(), model.format().columns_per_packet, options.cast_ahead_ns > 0)) {
  for (int i = 0; i <= std::max(1, options_.frames_ahead); ++i) {
    auto slot = std::make_unique<Slot>();
    slot->encoded = model_.make_frame_buffer();
    slot->freshness.resize(model_.packet_columns().size());
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
  return model_.packet(slot.encoded, index);
}

bool RenderAhead::observed(uint64_t frame, size_t index) const {
  return model_.packet_observed(slots_[frame % slots_.size()]->encoded, index);
}

PoseFreshness RenderAhead::freshness(uint64_t frame, size_t index) const {
  return slots_[frame % slots_.size()]->freshness[index];
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

bool RenderAhead::wait_until(int64_t steady_ns) {
  std::unique_lock lock(mutex_);
  const auto deadline = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(steady_ns));
  wake_.wait_until(lock, deadline, [&] { return stopping_ || steady_now_ns() >= steady_ns; });
  return !stopping_;
}

void RenderAhead::run() {
  uint64_t frame = 0;
  try {
    run_at_normal_priority(options_.worker_nice);
    while (wait_for_room(frame)) {
      render_frame(frame, *slots_[frame % slots_.size()]);
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
  for (const auto& [begin, end] : chunks_) {
    if (options_.cast_ahead_ns > 0) {
      const int64_t due = timing_.steady_ns(model_.packet_timestamp_ns(frame, begin) - timing_.clock.origin_ns);
      if (!wait_until(due - options_.cast_ahead_ns)) return;
    }
    if (abandoned(frame)) return;
    const PoseFreshness freshness = model_.poses().freshness();  // before the cast: what it can use
    const int64_t began = steady_now_ns();
    unposed_columns_.fetch_add(model_.render(frame, begin, end, slot.encoded), std::memory_order_relaxed);
    busy_ns_.fetch_add(static_cast<uint64_t>(steady_now_ns() - began), std::memory_order_relaxed);
    for (size_t i = begin; i < end; ++i) slot.freshness[i] = freshness;
    slot.ready.store(end, std::memory_order_release);
  }
}

}  // namespace lidartwin::streamer_detail
