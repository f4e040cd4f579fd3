// The forward model's cast stage: a block of a frame's columns cast, with edge partners.
#include "lidartwin/frame/cast_stage.h"

#include <array>
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

ColumnContext CastStage::context(const FrameColumns& columns, int m) const {
  ColumnContext c = wire_;
  c.frame = columns.frame_index;
  c.column = static_cast<uint32_t>(m);
  if (!columns.times_s.empty()) c.time_s = columns.times_s[static_cast<size_t>(m)];
  return c;
}

void CastStage::cast(const FrameColumns& columns, int begin, int end, Block& block) const {
  assert(0 <= begin && begin <= end && static_cast<size_t>(end - begin) <= block.ideal_.size());
  block.begin_ = begin;
  block.cast_.clear();
  for (int m = begin; m < end; ++m) {
    const auto column = static_cast<size_t>(m);
    if (!columns.observed[column]) continue;
    const Pose* pose = &columns.poses[column];
    if (moves_) pose = &(block.moved_[static_cast<size_t>(m - begin)] = chain_.moved_pose(*pose, context(columns, m)));
    block.cast_.push_back({m, pose, block.ideal_[static_cast<size_t>(m - begin)]});
  }
  caster_.cast(block.cast_);
  if (partners_) find_partners(columns, begin, end, block);
}

// E6's edge partners of the block's columns, from their rows above and below and the adjacent
// columns (choose_edge_partner). The columns just beyond the block are cast here, from the pose of
// the block's column beside each, and only where that column hit (a partner is chosen for hits
// alone): the two together, eight rows of both per packet, which Embree traverses faster than
// sixteen rows of one, and the sky beside a block is not cast at all.
void CastStage::find_partners(const FrameColumns& columns, int begin, int end, Block& block) const {
  const auto width = static_cast<int>(columns.observed.size());
  const auto observed = [&](int m) { return columns.observed[static_cast<size_t>((m + width) % width)] != 0; };
  std::array<ColumnCaster::Column, 2> beside;
  size_t n = 0;
  if (observed(begin)) {
    beside[n++] = {(begin - 1 + width) % width, &columns.poses[static_cast<size_t>(begin)], block.before_,
                   block.ideal_.front()};
  }
  if (observed(end - 1)) {
    beside[n++] = {end % width, &columns.poses[static_cast<size_t>(end - 1)], block.after_,
                   block.ideal_[static_cast<size_t>(end - 1 - begin)]};
  }
  if (n > 0) caster_.cast(std::span<const ColumnCaster::Column>(beside.data(), n));
  const auto cast_column = [&](int m) -> std::span<const IdealReturn> {
    if (m < begin) return block.before_;
    if (m >= end) return block.after_;
    return observed(m) ? std::span<const IdealReturn>(block.ideal_[static_cast<size_t>(m - begin)])
                       : std::span<const IdealReturn>();
  };
  for (int m = begin; m < end; ++m) {
    if (!observed(m)) continue;
    find_edge_partners(block.ideal_[static_cast<size_t>(m - begin)], cast_column(m - 1), cast_column(m + 1), geometry_);
  }
}

}  // namespace lidartwin
