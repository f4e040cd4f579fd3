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
    auto slot = std::make_unique<Slot>(model_.packet_columns().size());
    slot->encoded = model_.make_frame_buffer();
    slots_.push_back(std::move(slot));
  }
  worker_ = std::thread([this] { run(); });
}

RenderAhead::~RenderAhead() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  next_needed_.store(kStopping, std::memory_order_release);  // abandon the frame in progress
  next_needed_.notify_all();
  wake_.notify_all();
  worker_.join();
}

RenderAhead::Slot::Slot(size_t packets) : packet_frame(packets), freshness(packets) {
  for (auto& frame : packet_frame) frame.store(UINT64_MAX, std::memory_order_relaxed);
}

std::span<const uint8_t> RenderAhead::packet(uint64_t frame, size_t index) const {
  const Slot& slot = *slots_[frame % slots_.size()];
  if (slot.packet_frame[index].load(std::memory_order_acquire) != frame) return {};
  return model_.packet(slot.encoded, index);
}

bool RenderAhead::observed(uint64_t frame, size_t index) const {
  return model_.packet_observed(slots_[frame % slots_.size()]->encoded, index);
}

PoseFreshness RenderAhead::freshness(uint64_t frame, size_t index) const {
  return slots_[frame % slots_.size()]->freshness[index];
}

// Called by the send clock, which must never wait for the worker: no lock is taken (a lock held by
// a preempted worker would stall a real-time sender). The worker sleeps on next_needed_ itself, an
// atomic wait (a futex) that a store and notify cannot slip past, so it wakes once per frame sent.
// (It used to recheck every 2 ms instead: 500 wake-ups a second per sensor, each costing 30-60 us
// of CPU on a VM, a third of a core for a rig of 16.)
void RenderAhead::finished(uint64_t frame) {
  next_needed_.store(frame + 1, std::memory_order_release);
  next_needed_.notify_all();
}

bool RenderAhead::wait_for_room(uint64_t& frame) {
  for (;;) {
    const uint64_t needed = next_needed_.load(std::memory_order_acquire);
    if (needed == kStopping) return false;
    frame = std::max(frame, needed);
    // A frame's slot is free once the sender finished the frame that used it slots_.size() ago.
    if (frame < needed + slots_.size()) return true;
    next_needed_.wait(needed, std::memory_order_acquire);
  }
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

int64_t RenderAhead::deadline_ns(uint64_t frame, size_t index) const {
  return timing_.steady_ns(model_.packet_timestamp_ns(frame, index) - timing_.clock.origin_ns);
}

// The first packet of [begin, end) that can still be cast before it is due, one packet's casting
// time from now (the last chunk's); see the file comment.
size_t RenderAhead::first_in_time(uint64_t frame, size_t begin, size_t end) const {
  const int64_t ready_ns = steady_now_ns() + packet_ns_;
  while (begin < end && deadline_ns(frame, begin) < ready_ns) ++begin;
  return begin;
}

void RenderAhead::render_frame(uint64_t frame, Slot& slot) {
  for (auto [begin, end] : chunks_) {
    if (options_.cast_ahead_ns > 0 && !wait_until(deadline_ns(frame, begin) - options_.cast_ahead_ns)) return;
    if (abandoned(frame)) return;
    begin = first_in_time(frame, begin, end);
    if (begin == end) {
      packet_ns_ -= packet_ns_ / 8;  // no cast to measure: let the estimate fall back towards the truth
      continue;
    }
    const PoseFreshness freshness = model_.poses().freshness();  // before the cast: what it can use
    for (size_t i = begin; i < end; ++i) slot.freshness[i] = freshness;
    const int64_t began = steady_now_ns();
    const size_t unposed = model_.render(frame, begin, end, slot.encoded, [&slot, frame](size_t index) {
      slot.packet_frame[index].store(frame, std::memory_order_release);
    });
    const int64_t took = steady_now_ns() - began;
    unposed_columns_.fetch_add(unposed, std::memory_order_relaxed);
    busy_ns_.fetch_add(static_cast<uint64_t>(took), std::memory_order_relaxed);
    packet_ns_ = (3 * packet_ns_ + took / static_cast<int64_t>(end - begin)) / 4;
  }
}

}  // namespace lidartwin::streamer_detail
