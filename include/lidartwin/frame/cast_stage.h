#pragma once
// The forward model's first stage, a walk along consecutive blocks of a frame's columns: each
// observed column's beams cast from its own pose, E6's edge partners from the columns beside it
// (the next block's own cast), and the context each column's effects see.
// Everything that models pixels calls it: the renderer (`record`, `serve`) simulates the effect
// chain on what it casts, the analysis (`compare`, `--diagnose`, `fit`) predicts it. One function,
// so that the two cannot drift: which columns are cast, from where, how far, which neighbours are
// partners, which time drives E12.
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
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

// Where a column was observed from and when (the caller's own rule for its columns), for a column
// beside a block: the same answer the block that holds it gets.
struct LocatedColumn {
  Pose pose;            // world_from_sensor
  double time_s = 0.0;  // as FrameColumns::times_s
};
// Column m of the frame (0 <= m < width): located, or nullopt when it was not observed.
using ColumnLocator = std::function<std::optional<LocatedColumn>(int m)>;

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

  // One block of a frame's columns as cast: each observed column's returns, with edge partners
  // once the walk has passed it.
  class Block {
   public:
    Block(size_t columns, size_t rows);
    // Column m's ideal returns (m in the block; observed columns only).
    std::span<const IdealReturn> column(int m) const { return ideal_[static_cast<size_t>(m - begin_)]; }
    int begin() const { return begin_; }  // its first column

   private:
    friend class CastStage;
    int begin_ = 0, end_ = 0;
    std::vector<std::vector<IdealReturn>> ideal_;  // [column of the block][row]
    std::vector<IdealReturn> before_, after_;      // the columns beside the block, for edge partners
    bool has_before_ = false;                      // before_ holds the column before the block
    bool before_pending_ = false;                  // the column before is still to be cast
    std::vector<ColumnCaster::Column> cast_;       // the block's observed columns, cast together
    std::vector<Pose> moved_;                      // their poses moved by E11, when the chain moves them
    Pose before_pose_, after_pose_;                // of the columns cast beside the block
  };

  // One worker's walk along consecutive blocks of one frame, reused walk after walk: the block
  // being finished and the next, cast ahead, whose first column is the finished block's right
  // neighbour. A column beside a block is so cast once, by the block that holds it, and only a
  // walk's two ends cast a neighbour of their own.
  class Walk {
   public:
    Walk(size_t columns, size_t rows) : blocks_{Block(columns, rows), Block(columns, rows)} {}

   private:
    friend class CastStage;
    std::array<Block, 2> blocks_;
    size_t current_ = 0;
  };
  Walk make_walk(size_t block_columns) const { return Walk(block_columns, static_cast<size_t>(geometry_.rows())); }

  // Walks `count` blocks of `width` columns of one frame from column `first` (width at most the
  // walk's block width): prepare(begin) puts the columns of the block starting at `begin` in
  // `columns` (observed, pose, time), done(block) takes each block in order once its edge partners
  // are found (final until done returns). `locate` answers for the columns beside the walk's two
  // ends (any column of the frame, as prepare would).
  void walk(FrameColumns& columns, int first, int count, int width, const ColumnLocator& locate, Walk& walk,
            const std::function<void(int begin)>& prepare, const std::function<void(const Block&)>& done) const;

  // What column m's effects see: the wire's context, with the column's frame, measurement id and time.
  ColumnContext context(const FrameColumns& columns, int m) const;

  const BeamGeometry& geometry() const { return geometry_; }
  float reach_m() const { return caster_.max_range_m(); }

 private:
  // The walk's steps: its first block cast; the next block cast (next_end == the current block's
  // end: none) and the current one's partners found.
  void start(const FrameColumns& columns, int begin, int end, Walk& walk) const;
  const Block& advance(const FrameColumns& columns, int next_end, const ColumnLocator& locate, Walk& walk) const;
  void cast_block(const FrameColumns& columns, int begin, int end, Block& block) const;
  // How column `beside` (just before or after the block) is cast into the block's before_ or
  // after_, where the block's edge column hit: from its own pose when it lies in the frame, from the
  // edge column's when it lies in the next or previous frame. False: it is no one's partner.
  bool plan_beside(const FrameColumns& columns, int beside, const ColumnLocator& locate, Block& block,
                   ColumnCaster::Column& column) const;
  Pose cast_pose(const Pose& pose, const ColumnContext& context) const;  // moved by E11 when simulating
  ColumnContext context_at(uint64_t frame, int m, double time_s) const;
  void find_partners(const FrameColumns& columns, Block& block, std::span<const IdealReturn> right) const;

  BeamGeometry geometry_;
  const EffectChain& chain_;
  ColumnCaster caster_;
  ColumnContext wire_;
  bool moves_;     // casts from E11's moved poses
  bool partners_;  // finds E6's edge partners
};

}  // namespace lidartwin
