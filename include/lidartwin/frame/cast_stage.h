#pragma once
// The forward model's first stage, one block of a frame's columns at a time: each observed column's
// beams cast from its own pose, E6's edge partners, and the context each column's effects see.
// Everything that models pixels calls it: the renderer (`record`, `serve`) simulates the effect
// chain on what it casts, the analysis (`compare`, `--diagnose`, `fit`) predicts it. One function,
// so that the two cannot drift: which columns are cast, from where, how far, which neighbours are
// partners, which time drives E12.
#include <cstdint>
#include <span>
#include <vector>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/caster/column_caster.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/profile/beam_intrinsics.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

// The columns of one frame, indexed by measurement id: where the sensor was when each was observed,
// and whether it was observed at all (in the column window, with a pose to cast from; in a capture,
// a column whose packet arrived valid).
struct FrameColumns {
  uint64_t frame_index = 0;       // keys the noise (with seed, column, beam)
  std::vector<Pose> poses;        // [W] world_from_sensor
  std::vector<uint8_t> observed;  // [W] 0: no cast, zero pixels
  std::vector<double> times_s;    // [W] since the sensor's clock (or the capture) began: E12; empty: 0
};

class CastStage {
 public:
  // What the cast is for. kSimulate casts each column from the pose the chain moves it to (E11, the
  // mount's jitter) and finds edge partners when the chain reads them. kPredict casts from the
  // trajectory's pose (predict models the jitter as spread) and always finds partners, so that a
  // diagnosis can test mixed pixels on a chain without them.
  enum class Use : uint8_t { kSimulate, kPredict };

  // The beams as a unit's intrinsics say, `width` columns a turn. scene and chain must outlive the
  // stage; `wire` is the context every column shares (wire_context), `reach_m` how far rays look
  // (cast_reach_m).
  CastStage(const Scene& scene, const BeamIntrinsics& beams, int width, float reach_m, const EffectChain& chain,
            const ColumnContext& wire, Use use);
  CastStage(const CastStage&) = delete;  // its caster refers to its geometry
  CastStage& operator=(const CastStage&) = delete;

  // One worker's buffers for blocks of up to `columns` columns, reused block after block.
  class Block {
   public:
    Block(size_t columns, size_t rows);
    // Column m's ideal returns after cast() (m in the block; observed columns only).
    std::span<const IdealReturn> column(int m) const { return ideal_[static_cast<size_t>(m - begin_)]; }

   private:
    friend class CastStage;
    int begin_ = 0;
    std::vector<std::vector<IdealReturn>> ideal_;  // [column of the block][row]
    std::vector<IdealReturn> before_, after_;      // the columns beside the block, for edge partners
    std::vector<ColumnCaster::Column> cast_;       // the block's observed columns, cast together
    std::vector<Pose> moved_;                      // their poses moved by E11, when the chain moves them
  };
  Block make_block(size_t columns) const { return Block(columns, static_cast<size_t>(geometry_.rows())); }

  // Casts the observed columns of [begin, end) of one frame (at most the block's width, within the
  // frame) into block, all of them before any partner is chosen. Unobserved columns are not cast
  // and are no one's partner; the columns just beyond the block are cast again from the pose of
  // the block's column beside them (a column's time apart: the same place; not moved by E11, whose
  // jitter between neighbours is far below a depth step), so that a block needs no other block.
  void cast(const FrameColumns& columns, int begin, int end, Block& block) const;

  // What column m's effects see: the wire's context, with the column's frame, measurement id and time.
  ColumnContext context(const FrameColumns& columns, int m) const;

  const BeamGeometry& geometry() const { return geometry_; }
  float reach_m() const { return caster_.max_range_m(); }

 private:
  void find_partners(const FrameColumns& columns, int begin, int end, Block& block) const;

  BeamGeometry geometry_;
  const EffectChain& chain_;
  ColumnCaster caster_;
  ColumnContext wire_;
  bool moves_;     // casts from E11's moved poses
  bool partners_;  // finds E6's edge partners
};

}  // namespace lidartwin
