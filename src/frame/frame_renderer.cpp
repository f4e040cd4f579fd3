// The pixels of a frame, a packet's columns at a time: cast -> effects -> protocol units.
#include "lidartwin/frame/frame_renderer.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <vector>

#include "frame/channel_encoder.h"
#include "lidartwin/caster/column_caster.h"
#include "lidartwin/frame/wire_context.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin {
namespace {

// Per-worker buffers, so the hot loop allocates nothing: the ideal returns of a block of columns
// (cast first, all of them), and one column of measurements (the effect chain, column by column).
struct Scratch {
  std::vector<std::vector<IdealReturn>> ideal;  // [column of the block][row]
  MeasuredColumn measured;
  std::vector<IdealReturn> before, after;  // the columns beside the block, for edge partners (E6)
  std::vector<ColumnCaster::Column> cast;  // the block's observed columns, cast together
  std::vector<Pose> moved;                 // their poses moved by E11, when the chain moves them
};

}  // namespace

struct FrameRenderer::Impl {
  Impl(const Scene& scene, RenderSetup render_setup, WorkerPool& worker_pool)
      : setup(std::move(render_setup)),
        packets(setup.format),
        geometry(setup.beams, setup.format.columns_per_frame),
        cast_range(cast_reach_m(setup.max_range_m, packets)),
        caster(scene, geometry, cast_range),
        encoder(packets),
        partners(setup.chain.needs_edge_partners()),
        moves(setup.chain.moves_sensor()),
        pool(worker_pool) {
    assert(setup.beams.pixels_per_column() == setup.format.pixels_per_column);
    context = wire_context(packets, setup.signal_gain);
    context.seed = setup.seed;
    const auto rows = static_cast<size_t>(setup.format.pixels_per_column);
    const auto block = static_cast<size_t>(setup.format.columns_per_packet);
    scratch.assign(static_cast<size_t>(pool.size()),
                   Scratch{std::vector<std::vector<IdealReturn>>(block, std::vector<IdealReturn>(rows)),
                           MeasuredColumn(rows),
                           std::vector<IdealReturn>(rows),
                           std::vector<IdealReturn>(rows),
                           {},
                           std::vector<Pose>(block)});
  }

  // E6's edge partners of the block's columns, from their rows above and below and the adjacent
  // columns. The columns just outside the block are cast again here, from the pose of the block's
  // column beside them (a column's time apart: the same place; not moved by vibration, whose
  // jitter between neighbours is far below a depth step); unobserved columns in the block were not
  // cast and give no partners.
  void find_partners(const FrameColumns& columns, int begin, int end, Scratch& s) const {
    const int width = setup.format.columns_per_frame;
    const auto observed = [&](int m) { return columns.observed[static_cast<size_t>((m + width) % width)] != 0; };
    if (observed(begin)) caster.cast((begin - 1 + width) % width, columns.poses[static_cast<size_t>(begin)], s.before);
    if (observed(end - 1)) caster.cast(end % width, columns.poses[static_cast<size_t>(end - 1)], s.after);
    const auto cast_column = [&](int m) -> std::span<const IdealReturn> {
      if (m < begin) return s.before;
      if (m >= end) return s.after;
      return observed(m) ? std::span<const IdealReturn>(s.ideal[static_cast<size_t>(m - begin)])
                         : std::span<const IdealReturn>();
    };
    for (int m = begin; m < end; ++m) {
      if (!observed(m)) continue;
      find_edge_partners(s.ideal[static_cast<size_t>(m - begin)], cast_column(m - 1), cast_column(m + 1), geometry);
    }
  }

  // Columns [begin, end) of one packet. All of them are cast before any goes through the effect
  // chain: Embree's traversal and the chain's tables each stay in cache across the block instead
  // of evicting each other column by column (pipeline_bench: ratio to raw Embree 0.71 -> 0.75).
  void render_block(const FrameColumns& columns, int begin, int end, Scan& scan, Scratch& s) const {
    s.cast.clear();
    for (int m = begin; m < end; ++m) {
      const auto column = static_cast<size_t>(m);
      if (!columns.observed[column]) continue;
      const Pose* pose = &columns.poses[column];
      if (moves)
        pose = &(s.moved[static_cast<size_t>(m - begin)] = setup.chain.moved_pose(*pose, column_context(columns, m)));
      s.cast.push_back({m, pose, s.ideal[static_cast<size_t>(m - begin)]});
    }
    caster.cast(s.cast);
    if (partners) find_partners(columns, begin, end, s);
    for (int m = begin; m < end; ++m) {
      if (!columns.observed[static_cast<size_t>(m)]) {  // 6.4: zero pixels
        encoder.clear(m, scan);
        continue;
      }
      setup.chain.simulate(s.ideal[static_cast<size_t>(m - begin)], column_context(columns, m), s.measured);
      encoder.write(s.measured, m, scan);
    }
  }

  ColumnContext column_context(const FrameColumns& columns, int m) const {
    ColumnContext c = context;
    c.frame = columns.frame_index;
    c.column = static_cast<uint32_t>(m);
    if (!columns.times_s.empty()) c.time_s = columns.times_s[static_cast<size_t>(m)];
    return c;
  }

  RenderSetup setup;
  PacketFormat packets;
  BeamGeometry geometry;
  float cast_range;
  ColumnCaster caster;
  frame_detail::ChannelEncoder encoder;
  bool partners;  // the chain reads edge partners (E6)
  bool moves;     // the chain moves the sensor (E11): columns are cast from the moved pose
  ColumnContext context;
  WorkerPool& pool;
  mutable std::vector<Scratch> scratch;  // one per pool worker
};

FrameRenderer::FrameRenderer(const Scene& scene, RenderSetup setup, WorkerPool& pool)
    : impl_(std::make_unique<Impl>(scene, std::move(setup), pool)) {}

FrameRenderer::~FrameRenderer() = default;

const LidarDataFormat& FrameRenderer::format() const { return impl_->setup.format; }
const BeamGeometry& FrameRenderer::geometry() const { return impl_->geometry; }
float FrameRenderer::cast_range_m() const { return impl_->cast_range; }

void FrameRenderer::render(const FrameColumns& columns, int first, int last, Scan& scan, const BlockHook& done,
                           const BlockHook& prepare) const {
  const Impl& impl = *impl_;
  const LidarDataFormat& format = impl.setup.format;
  assert(scan.width == format.columns_per_frame && scan.height == format.pixels_per_column);
  assert(columns.poses.size() == static_cast<size_t>(scan.width) && columns.observed.size() == columns.poses.size());
  assert(0 <= first && first <= last && last <= scan.width);
  if (first == last) return;
  // Work items are packets' worth of columns, so a finished item is a packet ready to encode.
  const int block = format.columns_per_packet;
  const int first_block = first / block;
  const int blocks = (last - 1) / block - first_block + 1;
  impl.pool.run(blocks, [&](int worker, int item) {
    const int begin = std::max(first, (first_block + item) * block);
    const int end = std::min(last, (first_block + item + 1) * block);
    if (prepare) prepare(begin, end);
    impl.render_block(columns, begin, end, scan, impl.scratch[static_cast<size_t>(worker)]);
    if (done) done(begin, end);
  });
}

}  // namespace lidartwin
