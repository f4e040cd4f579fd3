#include "streamer/render_ahead.h"

#include <algorithm>

#include <spdlog/spdlog.h>

#include "lidartwin/frame/worker_pool.h"
#include "streamer/session_timing.h"

namespace lidartwin::streamer_detail {

namespace {
// Columns rendered per call: small enough that the first packets of a frame are ready long before
// the frame is done, large enough to keep the worker pool busy.
constexpr int kColumnsPerChunk = 128;
// A packet is cast again only if that can end this long before it is due, beyond one packet's
// casting time: a second cast that ends after the sender took the first copy costs CPU for nothing.
constexpr int64_t kRecastSlackNs = 50'000;
// When a pose arrives, the packets due within a packet's period plus this are cast again at once:
// the soonest packet the pose can still reach is among them. A packet due later (cast far ahead: a
// large cast_ahead on a busy host) is cast again once, as late as it safely can be, with the newest
// pose then (it can be cast again only once, and poses keep coming).
constexpr int64_t kRecastHorizonNs = 1'000'000;
// How much earlier than its casting time needs a late second cast starts: the worker's wake-up
// from a timed wait (p99 0.18 ms on a 2-core VM).
constexpr int64_t kWakeMarginNs = 200'000;
constexpr uint64_t kNothing = UINT64_MAX;  // Slot::published before the worker's first cast

std::vector<std::pair<size_t, size_t>> plan_chunks(size_t packets, int columns_per_packet) {
  const size_t per_chunk = static_cast<size_t>(std::max(1, kColumnsPerChunk / columns_per_packet));
  std::vector<std::pair<size_t, size_t>> chunks;
  for (size_t begin = 0; begin < packets; begin += per_chunk)
    chunks.emplace_back(begin, std::min(packets, begin + per_chunk));
  return chunks;
}
}  // namespace

RenderAhead::RenderAhead(const ForwardModel& model, const SessionTiming& timing, Options options, PoseNews* news)
    : model_(model),
      timing_(timing),
      options_(options),
      chunks_(plan_chunks(model.packet_columns().size(), model.format().columns_per_packet)),
      recast_horizon_ns_(static_cast<int64_t>(timing.clock.frame_period_ns() / model.packet_columns().size()) +
                         kRecastHorizonNs),
      news_(news ? *news : own_news_) {
  const size_t copies = options_.cast_ahead_ns > 0 ? 2 : 1;
  for (int i = 0; i <= std::max(1, options_.frames_ahead); ++i) {
    auto slot = std::make_unique<Slot>(model_.packet_columns().size(), copies);
    for (EncodedFrame& copy : slot->copies) copy = model_.make_frame_buffer();
    slots_.push_back(std::move(slot));
  }
  worker_ = std::thread([this] { run(); });
}

RenderAhead::~RenderAhead() {
  stopping_.store(true);
  next_needed_.store(kStopping, std::memory_order_release);  // abandon the frame in progress
  next_needed_.notify_all();
  news_.interrupt();
  worker_.join();
}

RenderAhead::Slot::Slot(size_t packets, size_t copy_count)
    : published(packets), copies(copy_count), freshness(copy_count, std::vector<PoseFreshness>(packets)) {
  for (auto& word : published) word.store(kNothing, std::memory_order_relaxed);
}

std::optional<RenderAhead::Ready> RenderAhead::ready(uint64_t frame, size_t index) const {
  const Slot& s = slot(frame);
  const uint64_t word = s.published[index].load(std::memory_order_acquire);
  if (word == kNothing || word >> 1 != frame) return std::nullopt;
  const size_t copy = word & 1;
  return Ready{model_.packet(s.copies[copy], index), &s.copies[copy], s.freshness[copy][index]};
}

// Called by the send clock, which must never wait for the worker: no lock is taken (a lock held by
// a preempted worker would stall a real-time sender). The worker sleeps on next_needed_ itself, an
// atomic wait (a futex) that a store and notify cannot slip past, so it wakes once per frame sent
// (a recheck every 2 ms would be 500 wake-ups a second per sensor, each costing 30-60 us of CPU on
// a VM: a third of a core for a rig of 16).
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

void RenderAhead::run() {
  try {
    run_at_normal_priority(options_.worker_nice);
    if (options_.cast_ahead_ns > 0) {
      run_paced();
      return;
    }
    for (uint64_t frame = 0; wait_for_room(frame); ++frame) render_frame(frame);
  } catch (const std::exception& e) {
    // A bug, not bad input (the config was validated before the reinit): the send clock keeps
    // going and reports every packet it cannot fill as a render stall.
    spdlog::error("streamer: rendering stopped: {}", e.what());
  }
}

int64_t RenderAhead::deadline_ns(uint64_t frame, size_t index) const {
  return timing_.steady_ns_of_timestamp(model_.packet_timestamp_ns(frame, index));
}

// The first packet of [begin, end) that can still be cast before it is due, one packet's casting
// time from now (the smoothed estimate); see the file comment.
size_t RenderAhead::first_in_time(uint64_t frame, size_t begin, size_t end) const {
  const int64_t ready_ns = steady_now_ns() + packet_ns_;
  while (begin < end && deadline_ns(frame, begin) < ready_ns) ++begin;
  return begin;
}

void RenderAhead::cast(uint64_t frame, size_t begin, size_t end, size_t copy) {
  Slot& s = slot(frame);
  const PoseFreshness freshness = model_.poses().freshness();  // before the cast: what it can use
  for (size_t i = begin; i < end; ++i) s.freshness[copy][i] = freshness;
  const int64_t began = steady_now_ns();
  const size_t unposed = model_.render(frame, begin, end, s.copies[copy], [&s, frame, copy](size_t index) {
    s.published[index].store(frame << 1 | copy, std::memory_order_release);
  });
  const int64_t took = steady_now_ns() - began;
  if (copy == 0) unposed_columns_.fetch_add(unposed, std::memory_order_relaxed);
  busy_ns_.fetch_add(static_cast<uint64_t>(took), std::memory_order_relaxed);
  packet_ns_ = (3 * packet_ns_ + took / static_cast<int64_t>(end - begin)) / 4;
}

// Unpaced: whole frames as far ahead as the slots allow, a chunk of packets per call.
void RenderAhead::render_frame(uint64_t frame) {
  for (auto [begin, end] : chunks_) {
    if (abandoned(frame)) return;
    begin = first_in_time(frame, begin, end);
    if (begin == end) {
      packet_ns_ -= packet_ns_ / 8;  // no cast to measure: let the estimate fall back towards the truth
      continue;
    }
    cast(frame, begin, end, 0);
  }
}

// Paced: one packet at a time, each cast_ahead before it is due, and once more if a pose arrives
// while it still can be (the file comment).
void RenderAhead::run_paced() {
  const size_t packets = model_.packet_columns().size();
  std::vector<Position> cast_once;  // cast with poses that may yet be superseded, in send order
  Position next;
  for (;;) {
    const uint64_t frame = next.frame;
    if (!wait_for_room(next.frame)) return;
    if (next.frame != frame) next.index = 0;  // the sender moved past frames not yet cast
    if (!wait_recasting(deadline_ns(next.frame, next.index) - options_.cast_ahead_ns, cast_once)) return;
    if (abandoned(next.frame)) {
      next = {next.frame + 1, 0};
      continue;
    }
    if (first_in_time(next.frame, next.index, next.index + 1) == next.index) {
      cast(next.frame, next.index, next.index + 1, 0);
      cast_once.push_back(next);
    } else {
      packet_ns_ -= packet_ns_ / 8;  // no cast to measure: let the estimate fall back towards the truth
    }
    next = next.index + 1 < packets ? Position{next.frame, next.index + 1} : Position{next.frame + 1, 0};
  }
}

bool RenderAhead::wait_recasting(int64_t steady_ns, std::vector<Position>& cast_once) {
  for (;;) {
    // Poses counted in `seen` were added to the source before they were counted: recast() sees
    // them, including any that arrived while the worker was casting.
    const uint64_t seen = news_.count();
    const int64_t late_ns = recast(cast_once, seen != news_handled_);
    news_handled_ = seen;
    if (steady_now_ns() >= steady_ns) return !stopping_.load();
    news_.wait_until(std::min(steady_ns, late_ns), seen, [this] { return stopping_.load(); });
    if (stopping_.load()) return false;
  }
}

// Each packet cast before the newest pose arrived is cast again into its second copy (once: see the
// file comment), soonest due first, while that can end before it is due: at once if a pose just
// arrived and it is due within the horizon, else at its late point. Returns the earliest late point
// of the packets left waiting for one (steady clock), or INT64_MAX.
int64_t RenderAhead::recast(std::vector<Position>& cast_once, bool news) {
  const uint64_t revision = model_.poses().freshness().revision;
  int64_t next_late_ns = INT64_MAX;
  size_t kept = 0;
  for (const Position& at : cast_once) {
    const int64_t deadline = deadline_ns(at.frame, at.index);
    const int64_t left_ns = deadline - steady_now_ns();
    if (abandoned(at.frame) || left_ns < packet_ns_ + kRecastSlackNs) continue;  // too late: dropped
    const bool stale = slot(at.frame).freshness[0][at.index].revision < revision;
    const int64_t late_ns = packet_ns_ + kRecastSlackNs + kWakeMarginNs;  // before the deadline
    if (stale && ((news && left_ns <= recast_horizon_ns_) || left_ns <= late_ns)) {
      cast(at.frame, at.index, at.index + 1, 1);
      recasts_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    if (stale) next_late_ns = std::min(next_late_ns, deadline - late_ns);
    cast_once[kept++] = at;
  }
  cast_once.resize(kept);
  return next_late_ns;
}

}  // namespace lidartwin::streamer_detail
