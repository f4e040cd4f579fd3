// The forward model's cast stage: blocks of a frame's columns cast in a walk, with edge partners.
#include "lidartwin/frame/cast_stage.h"

#include <algorithm>
#include <cassert>

namespace lidartwin {

CastStage::Block::Block(size_t columns, size_t rows)
    : ideal_(columns, std::vector<IdealReturn>(rows)), before_(rows), after_(rows), moved_(columns) {}

CastStage::CastStage(const Scene& scene, const BeamIntrinsics& beams, int width, float reach_m,
                     const EffectChain& chain, const ColumnContext& wire, Use use)
    : geometry_(beams, width),
      chain_(chain),
      caster_(scene, geometry_, reach_m),
      wire_(wire),
      moves_(use == Use::kSimulate && chain.moves_sensor()),
      partners_(use == Use::kPredict || chain.needs_edge_partners()) {}

ColumnContext CastStage::context_at(uint64_t frame, int m, double time_s) const {
  ColumnContext c = wire_;
  c.frame = frame;
  c.column = static_cast<uint32_t>(m);
  c.time_s = time_s;
  return c;
}

ColumnContext CastStage::context(const FrameColumns& columns, int m) const {
  return context_at(columns.frame_index, m, columns.times_s.empty() ? 0.0 : columns.times_s[static_cast<size_t>(m)]);
}

Pose CastStage::cast_pose(const Pose& pose, const ColumnContext& context) const {
  return moves_ ? chain_.moved_pose(pose, context) : pose;
}

void CastStage::cast_block(const FrameColumns& columns, int begin, int end, Block& block) const {
  assert(0 <= begin && begin <= end && static_cast<size_t>(end - begin) <= block.ideal_.size());
  block.begin_ = begin;
  block.end_ = end;
  block.cast_.clear();
  for (int m = begin; m < end; ++m) {
    const auto column = static_cast<size_t>(m);
    if (!columns.observed[column]) continue;
    const Pose* pose = &columns.poses[column];
    if (moves_) pose = &(block.moved_[static_cast<size_t>(m - begin)] = cast_pose(*pose, context(columns, m)));
    block.cast_.push_back({m, pose, block.ideal_[static_cast<size_t>(m - begin)]});
  }
  caster_.cast(block.cast_);
}

// Only where the block's edge column hit: a partner is chosen for hits alone, and the sky beside
// a block is not cast at all. A column of the same frame is cast as its own block casts it (its
// pose, moved by E11 when the chain moves the sensor), so a block's partners do not depend on
// which worker cast its neighbour; the previous or next frame's column, a column's time away, from
// the edge column's pose. Returns false when `beside` is no one's partner (not observed, or the
// edge column was not).
bool CastStage::plan_beside(const FrameColumns& columns, int beside, const ColumnLocator& locate, Block& block,
                            ColumnCaster::Column& column) const {
  const auto width = static_cast<int>(columns.observed.size());
  const bool before = beside < block.begin_;
  const int edge = before ? block.begin_ : block.end_ - 1;
  if (!columns.observed[static_cast<size_t>(edge)]) return false;
  Pose& pose = before ? block.before_pose_ : block.after_pose_;
  if (beside >= 0 && beside < width) {
    const std::optional<LocatedColumn> located = locate(beside);
    if (!located) return false;
    pose = cast_pose(located->pose, context_at(columns.frame_index, beside, located->time_s));
  } else {
    pose = columns.poses[static_cast<size_t>(edge)];
    beside = (beside + width) % width;
  }
  column = {beside, &pose, before ? block.before_ : block.after_, block.column(edge)};
  return true;
}

void CastStage::walk(FrameColumns& columns, int first, int count, int width, const ColumnLocator& locate, Walk& walk,
                     const std::function<void(int)>& prepare, const std::function<void(const Block&)>& done) const {
  prepare(first);
  start(columns, first, first + width, walk);
  for (int k = 1; k <= count; ++k) {
    const int end = first + k * width;
    if (k < count) prepare(end);
    done(advance(columns, k < count ? end + width : end, locate, walk));
  }
}

void CastStage::start(const FrameColumns& columns, int begin, int end, Walk& walk) const {
  Block& block = walk.blocks_[walk.current_];
  cast_block(columns, begin, end, block);
  block.has_before_ = false;
  block.before_pending_ = partners_;  // cast with the block's right neighbour when that is cast alone too
}

const CastStage::Block& CastStage::advance(const FrameColumns& columns, int next_end, const ColumnLocator& locate,
                                           Walk& walk) const {
  Block& block = walk.blocks_[walk.current_];
  Block& next = walk.blocks_[1 - walk.current_];
  const int end = block.end_;
  const bool walks_on = next_end > end;
  if (walks_on) cast_block(columns, end, next_end, next);
  walk.current_ = 1 - walk.current_;
  if (!partners_) return block;
  // The columns beside the block that no block of this walk casts, together: two columns, eight
  // rows of both per packet, which Embree traverses faster than sixteen rows of one.
  std::array<ColumnCaster::Column, 2> beside;
  size_t n = 0;
  if (block.before_pending_) {
    block.has_before_ = plan_beside(columns, block.begin_ - 1, locate, block, beside[n]);
    n += block.has_before_;
  }
  bool has_after = false;
  if (!walks_on) {
    has_after = plan_beside(columns, end, locate, block, beside[n]);
    n += has_after;
  }
  if (n > 0) caster_.cast(std::span<const ColumnCaster::Column>(beside.data(), n));
  std::span<const IdealReturn> right;
  if (walks_on && columns.observed[static_cast<size_t>(end)]) right = next.column(end);
  if (has_after) right = block.after_;
  find_partners(columns, block, right);
  if (walks_on) {  // the next block's left neighbour, before this block's buffers take the one after
    next.before_pending_ = false;
    next.has_before_ = columns.observed[static_cast<size_t>(end - 1)] != 0;
    if (next.has_before_) std::ranges::copy(block.column(end - 1), next.before_.begin());
  }
  return block;
}

// E6's edge partners of the block's columns, from their rows above and below and the adjacent
// columns (choose_edge_partner); unobserved columns are not cast and are no one's partner.
void CastStage::find_partners(const FrameColumns& columns, Block& block, std::span<const IdealReturn> right) const {
  const int begin = block.begin_, end = block.end_;
  const auto observed = [&](int m) { return columns.observed[static_cast<size_t>(m)] != 0; };
  const auto cast_column = [&](int m) -> std::span<const IdealReturn> {
    if (m < begin)
      return block.has_before_ ? std::span<const IdealReturn>(block.before_) : std::span<const IdealReturn>();
    if (m >= end) return right;
    return observed(m) ? block.column(m) : std::span<const IdealReturn>();
  };
  for (int m = begin; m < end; ++m) {
    if (!observed(m)) continue;
    find_edge_partners(block.ideal_[static_cast<size_t>(m - begin)], cast_column(m - 1), cast_column(m + 1), geometry_);
  }
}

}  // namespace lidartwin
