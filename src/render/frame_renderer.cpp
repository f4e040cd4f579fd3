// The forward sensor model, one column at a time: pose -> cast -> effects -> protocol units.
#include "lidartwin/render/frame_renderer.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <vector>

#include "lidartwin/caster/column_caster.h"
#include "lidartwin/packet/lidar_packet.h"
#include "render/channel_encoder.h"
#include "render/worker_pool.h"

namespace lidartwin {
namespace {

// Per-worker buffers, so the hot loop allocates nothing: the ideal returns of a block of columns
// (cast first, all of them), and one column of measurements (the effect chain, column by column).
struct Scratch {
  std::vector<std::vector<IdealReturn>> ideal;  // [column of the block][row]
  MeasuredColumn measured;
};

struct FrameJob {
  uint64_t frame_index;
  double frame_start_s;
  const Trajectory& trajectory;
  Scan& scan;
};

// Rays end 1 m past the profile's maximum range, so range noise can still carry a return across
// it and the effect chain's range_limits decide (E16), and never beyond what the wire can carry (E9).
float cast_limit_m(const SensorProfile& profile, const PacketFormat& packets) {
  const double wire_m = packets.channel_max(ChannelField::kRange) / 1000.0;
  return static_cast<float>(std::min(profile.max_range_m + 1.0, wire_m));
}

}  // namespace

struct FrameRenderer::Impl {
  Impl(const Scene& scene, const SensorProfile& profile, EffectChain effect_chain, const LidarDataFormat& format,
       RenderConfig render_config)
      : chain(std::move(effect_chain)),
        packets(format),
        config(render_config),
        geometry(profile.beams, format.columns_per_frame),
        cast_range(cast_limit_m(profile, packets)),
        caster(scene, geometry, cast_range),
        encoder(packets),
        pool(render_config.threads) {
    assert(profile.beams.pixels_per_column() == format.pixels_per_column);
    valid_status = format.udp_profile_lidar == UdpProfileLidar::kLegacy ? 0xFFFF'FFFFu : 1u;  // 4.2, 4.4
    context.seed = config.seed;
    context.range_step_m = static_cast<float>(packets.channel_step(ChannelField::kRange)) / 1000.0f;
    context.max_wire_range_m = static_cast<float>(packets.channel_max(ChannelField::kRange)) / 1000.0f;
    context.signal_gain = config.signal_gain;
    const auto rows = static_cast<size_t>(format.pixels_per_column);
    const auto block = static_cast<size_t>(format.columns_per_packet);
    scratch.assign(static_cast<size_t>(pool.size()),
                   Scratch{std::vector<std::vector<IdealReturn>>(block, std::vector<IdealReturn>(rows)),
                           MeasuredColumn(rows)});
  }

  const LidarDataFormat& format() const { return packets.format(); }

  // 6.1, E11: column m is observed m / (W * fps) after the frame starts.
  double column_time_s(const FrameJob& job, int m) const {
    return job.frame_start_s + m / (static_cast<double>(format().columns_per_frame) * format().fps);
  }
  uint64_t column_timestamp_ns(const FrameJob& job, int m) const {
    const uint64_t offset = static_cast<uint64_t>(m) * 1'000'000'000ull /
                            static_cast<uint64_t>(format().columns_per_frame * format().fps);
    return static_cast<uint64_t>(config.clock_origin_ns + std::llround(job.frame_start_s * 1e9)) + offset;
  }

  // Columns [begin, end) of one packet. All of them are cast before any goes through the effect
  // chain: Embree's traversal and the chain's tables each stay in cache across the block instead
  // of evicting each other column by column (pipeline_bench: ratio to raw Embree 0.71 -> 0.75).
  void render_block(const FrameJob& job, int begin, int end, Scratch& s) const {
    for (int m = begin; m < end; ++m) {
      job.scan.timestamp_ns[static_cast<size_t>(m)] = column_timestamp_ns(job, m);
      if (!column_in_window(format().column_window, m)) continue;
      caster.cast(m, job.trajectory.at(column_time_s(job, m)), s.ideal[static_cast<size_t>(m - begin)]);
    }
    for (int m = begin; m < end; ++m) {
      if (!column_in_window(format().column_window, m)) {  // 6.4: status 0, zero pixels
        job.scan.status[static_cast<size_t>(m)] = 0;
        encoder.clear(m, job.scan);
        continue;
      }
      ColumnContext column_context = context;
      column_context.frame = job.frame_index;
      column_context.column = static_cast<uint32_t>(m);
      chain.simulate(s.ideal[static_cast<size_t>(m - begin)], column_context, s.measured);
      encoder.write(s.measured, m, job.scan);
      job.scan.status[static_cast<size_t>(m)] = valid_status;
    }
  }

  EffectChain chain;
  PacketFormat packets;
  RenderConfig config;
  BeamGeometry geometry;
  float cast_range;
  ColumnCaster caster;
  render_detail::ChannelEncoder encoder;
  ColumnContext context;
  uint32_t valid_status = 1;
  mutable render_detail::WorkerPool pool;
  mutable std::vector<Scratch> scratch;  // one per pool worker
};

FrameRenderer::FrameRenderer(const Scene& scene, const SensorProfile& profile, EffectChain chain,
                             const LidarDataFormat& format, RenderConfig config)
    : impl_(std::make_unique<Impl>(scene, profile, std::move(chain), format, config)) {}

FrameRenderer::~FrameRenderer() = default;

const BeamGeometry& FrameRenderer::geometry() const { return impl_->geometry; }
int FrameRenderer::threads() const { return impl_->pool.size(); }
float FrameRenderer::cast_range_m() const { return impl_->cast_range; }

void FrameRenderer::render(uint64_t frame_index, double frame_start_s, const Trajectory& trajectory, int first,
                           int last, Scan& scan) const {
  render(frame_index, frame_start_s, trajectory, first, last, scan, nullptr);
}

void FrameRenderer::render(uint64_t frame_index, double frame_start_s, const Trajectory& trajectory, int first,
                           int last, Scan& scan, const BlockDone& block_done) const {
  const Impl& impl = *impl_;
  assert(scan.width == impl.format().columns_per_frame && scan.height == impl.format().pixels_per_column);
  assert(0 <= first && first <= last && last <= scan.width);
  if (first == last) return;
  // Work items are packets' worth of columns, so a finished item is a packet ready to encode.
  const int block = impl.format().columns_per_packet;
  const int first_block = first / block;
  const int blocks = (last - 1) / block - first_block + 1;
  const FrameJob job{frame_index, frame_start_s, trajectory, scan};
  impl.pool.run(blocks, [&](int worker, int item) {
    const int begin = std::max(first, (first_block + item) * block);
    const int end = std::min(last, (first_block + item + 1) * block);
    impl.render_block(job, begin, end, impl.scratch[static_cast<size_t>(worker)]);
    if (block_done) block_done(begin, end);
  });
}

}  // namespace lidartwin
