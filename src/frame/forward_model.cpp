// The forward model: each packet's columns located, stamped, cast, through the effect chain and
// encoded, on one worker.
#include "lidartwin/frame/forward_model.h"

#include <atomic>
#include <cassert>
#include <optional>

#include "frame/channel_encoder.h"
#include "lidartwin/frame/imu_model.h"
#include "lidartwin/frame/packet_plan.h"
#include "lidartwin/frame/wire_context.h"

namespace lidartwin {

using PacketReady = ForwardModel::PacketReady;

struct ForwardModel::Impl {
  // One worker's buffers, so the hot loop allocates nothing: the cast of a packet's columns, and
  // one column of measurements (the effect chain, column by column).
  struct Scratch {
    CastStage::Block block;
    MeasuredColumn measured;
  };

  Impl(const Scene& scene, const PoseSource& pose_source, ForwardModelSetup model_setup, WorkerPool& worker_pool)
      : poses(pose_source),
        clock{model_setup.render.format.columns_per_frame, model_setup.render.format.fps, model_setup.origin_ns,
              model_setup.pose_origin_s},
        init_id(model_setup.init_id),
        prod_sn(model_setup.prod_sn),
        packets(model_setup.render.format),  // validates the format first
        sensor_from_imu(lidartwin::sensor_from_imu(model_setup.render.beams.imu_to_sensor)),
        render(std::move(model_setup.render)),
        cast(scene, render.beams, render.format.columns_per_frame, cast_reach_m(render.max_range_m, packets),
             render.chain, column_context(), CastStage::Use::kSimulate),
        encoder(packets),
        pool(worker_pool),
        firsts(packets_to_send(packets.format())),
        per_column_poses(model_setup.per_column_poses) {
    assert(render.beams.pixels_per_column() == render.format.pixels_per_column);
    const LidarDataFormat& f = packets.format();
    valid_status = valid_column_status(f.udp_profile_lidar);
    index_of_first.assign(static_cast<size_t>(f.columns_per_frame / f.columns_per_packet), -1);
    for (size_t i = 0; i < firsts.size(); ++i) {
      index_of_first[static_cast<size_t>(firsts[i] / f.columns_per_packet)] = static_cast<int>(i);
    }
    for (int w = 0; w < pool.size(); ++w) {
      scratch.push_back({cast.make_block(static_cast<size_t>(f.columns_per_packet)),
                         MeasuredColumn(static_cast<size_t>(f.pixels_per_column))});
    }
  }

  ColumnContext column_context() const {
    ColumnContext context = wire_context(packets, render.signal_gain);
    context.seed = render.seed;
    return context;
  }

  const LidarDataFormat& format() const { return packets.format(); }
  int columns_per_packet() const { return format().columns_per_packet; }

  PacketHeader header_of(uint64_t frame) const {
    PacketHeader header;
    header.frame_id = frame_id_of(frame, format());
    header.init_id = init_id;
    header.prod_sn = prod_sn;
    return header;
  }

  std::span<uint8_t> slot(EncodedFrame& out, size_t index) const {
    const size_t size = packets.lidar_packet_size();
    return {out.bytes.data() + index * size, size};
  }

  // Columns [first, last) of frame k: from where each was observed, and whether at all (in the
  // column window, 6.4, with a pose the source stands behind). Without per-column poses every
  // column is cast from the frame's first column's pose (motion distortion left out). Returns the
  // columns in the window that had no pose.
  size_t locate_columns(uint64_t frame, int first, int last, const PoseSpan& span, FrameColumns& columns) const {
    const double frame_pose_time_s = clock.column_pose_time_s(frame, 0);
    size_t unposed = 0;
    for (int m = first; m < last; ++m) {
      const auto column = static_cast<size_t>(m);
      const double time_s = clock.column_pose_time_s(frame, m);
      const double pose_time_s = per_column_poses ? time_s : frame_pose_time_s;
      const bool in_window = column_in_window(format().column_window, m);
      columns.observed[column] = in_window && span.contains(pose_time_s);
      unposed += in_window && !columns.observed[column];
      columns.times_s[column] = time_s - clock.pose_origin_s;
      if (columns.observed[column]) columns.poses[column] = poses.at(pose_time_s);
    }
    return unposed;
  }

  // The timestamp (6.3) and status (4.2, 4.4) the packets carry for columns [first, last).
  void stamp_columns(uint64_t frame, int first, int last, const std::vector<uint8_t>* observed, Scan& scan) const {
    for (int m = first; m < last; ++m) {
      const auto column = static_cast<size_t>(m);
      scan.timestamp_ns[column] = clock.column_timestamp_ns(frame, m);
      scan.status[column] = observed && (*observed)[column] ? valid_status : 0u;
    }
  }

  // Packets [begin, end) whose columns are contiguous, one packet per work item: the worker that
  // takes a packet carries it through the whole model and hands its bytes on, so packets leave in
  // parallel with the rest of the frame's casting.
  size_t render_run(uint64_t frame, size_t begin, size_t end, EncodedFrame& out, const PacketReady& ready) const {
    const int cpp = columns_per_packet();
    assert(firsts[end - 1] + cpp - firsts[begin] == static_cast<int>(end - begin) * cpp);
    assert(out.scan.width == format().columns_per_frame &&
           out.columns.poses.size() == static_cast<size_t>(out.scan.width));
    out.columns.frame_index = frame;
    const PoseSpan span = poses.span();  // one answer for the whole run: a live span may grow meanwhile
    const PacketHeader header = header_of(frame);
    std::atomic<size_t> unposed{0};
    pool.run(static_cast<int>(end - begin), [&](int worker, int item) {
      const int first = firsts[begin] + item * cpp;
      Scratch& s = scratch[static_cast<size_t>(worker)];
      unposed.fetch_add(render_packet(frame, first, span, out, s), std::memory_order_relaxed);
      const int index = index_of_first[static_cast<size_t>(first / cpp)];
      packets.encode(header, out.scan, first, slot(out, static_cast<size_t>(index)));
      if (ready) ready(static_cast<size_t>(index));
    });
    return unposed.load();
  }

  // The columns of the packet that starts at column `first`, through the forward model: where
  // each was observed from, its timestamp and status, the cast (all its columns before any goes
  // through the chain: Embree's traversal and the chain's tables each stay in cache across the
  // packet instead of evicting each other column by column), the effect chain, protocol units.
  // Returns the columns in the window that had no pose.
  size_t render_packet(uint64_t frame, int first, const PoseSpan& span, EncodedFrame& out, Scratch& s) const {
    const int last = first + columns_per_packet();
    const size_t unposed = locate_columns(frame, first, last, span, out.columns);
    stamp_columns(frame, first, last, &out.columns.observed, out.scan);
    cast.cast(out.columns, first, last, s.block);
    for (int m = first; m < last; ++m) {
      if (!out.columns.observed[static_cast<size_t>(m)]) {  // 6.4: zero pixels
        encoder.clear(m, out.scan);
        continue;
      }
      render.chain.simulate(s.block.column(m), cast.context(out.columns, m), s.measured);
      encoder.write(s.measured, m, out.scan);
    }
    return unposed;
  }

  const PoseSource& poses;
  SensorClock clock;
  uint32_t init_id;
  uint64_t prod_sn;
  PacketFormat packets;
  Pose sensor_from_imu;
  RenderSetup render;
  CastStage cast;
  frame_detail::ChannelEncoder encoder;
  WorkerPool& pool;
  mutable std::vector<Scratch> scratch;  // one per pool worker
  std::vector<int> firsts;
  std::vector<int> index_of_first;  // packet slot in the frame -> index in firsts, -1 = not sent
  uint32_t valid_status = 1;
  bool per_column_poses = true;
  std::optional<ImuErrors> imu_errors;  // none: an exact IMU
};

ForwardModel::ForwardModel(const Scene& scene, const PoseSource& poses, ForwardModelSetup setup, WorkerPool& pool)
    : impl_(nullptr) {
  const ImuNoise imu_noise = setup.imu_noise;
  const uint64_t seed = setup.render.seed;
  impl_ = std::make_unique<Impl>(scene, poses, std::move(setup), pool);
  if (imu_noise.any()) impl_->imu_errors.emplace(imu_noise, seed, static_cast<double>(kImuPeriodNs) * 1e-9);
}

ForwardModel::~ForwardModel() = default;

const LidarDataFormat& ForwardModel::format() const { return impl_->format(); }
const SensorClock& ForwardModel::clock() const { return impl_->clock; }
const BeamGeometry& ForwardModel::geometry() const { return impl_->cast.geometry(); }
float ForwardModel::cast_range_m() const { return impl_->cast.reach_m(); }
const std::vector<int>& ForwardModel::packet_columns() const { return impl_->firsts; }
size_t ForwardModel::packet_size() const { return impl_->packets.lidar_packet_size(); }

EncodedFrame ForwardModel::make_frame_buffer() const {
  EncodedFrame frame;
  frame.scan = Scan(format());
  const auto width = static_cast<size_t>(format().columns_per_frame);
  frame.columns.poses.resize(width);
  frame.columns.times_s.resize(width);
  frame.columns.observed.assign(width, 0);
  frame.bytes.resize(impl_->firsts.size() * packet_size());
  return frame;
}

size_t ForwardModel::render(uint64_t frame, EncodedFrame& out, const PacketReady& ready) const {
  return render_packets(frame, 0, packet_columns().size(), out, ready);
}

size_t ForwardModel::render(uint64_t frame, size_t begin, size_t end, EncodedFrame& out) const {
  return render_packets(frame, begin, end, out, nullptr);
}

size_t ForwardModel::render(uint64_t frame, size_t begin, size_t end, EncodedFrame& out,
                            const PacketReady& ready) const {
  return render_packets(frame, begin, end, out, ready);
}

size_t ForwardModel::render_packets(uint64_t frame, size_t begin, size_t end, EncodedFrame& out,
                                    const PacketReady& ready) const {
  const auto& firsts = impl_->firsts;
  assert(begin <= end && end <= firsts.size());
  const int cpp = impl_->columns_per_packet();
  // A wrapping column window sends two runs of consecutive packets (6.4); render each as one.
  size_t unposed = 0;
  while (begin < end) {
    size_t run_end = begin + 1;
    while (run_end < end && firsts[run_end] == firsts[run_end - 1] + cpp) ++run_end;
    unposed += impl_->render_run(frame, begin, run_end, out, ready);
    begin = run_end;
  }
  return unposed;
}

bool ForwardModel::packet_observed(const EncodedFrame& frame, size_t index) const {
  const int first = impl_->firsts[index];
  for (int m = first; m < first + impl_->columns_per_packet(); ++m) {
    if (frame.columns.observed[static_cast<size_t>(m)]) return true;
  }
  return false;
}

const PoseSource& ForwardModel::poses() const { return impl_->poses; }

std::span<const uint8_t> ForwardModel::packet(const EncodedFrame& frame, size_t index) const {
  const size_t size = packet_size();
  return {frame.bytes.data() + index * size, size};
}

uint64_t ForwardModel::packet_timestamp_ns(uint64_t frame, size_t index) const {
  return impl_->clock.packet_timestamp_ns(frame, impl_->firsts[index], impl_->columns_per_packet());
}

std::span<const uint8_t> ForwardModel::blank_packet(uint64_t frame, size_t index, EncodedFrame& scratch) const {
  const Impl& impl = *impl_;
  const int first = impl.firsts[index];
  impl.stamp_columns(frame, first, first + impl.columns_per_packet(), nullptr, scratch.scan);
  const std::span<uint8_t> out = impl.slot(scratch, index);
  impl.packets.encode(impl.header_of(frame), scratch.scan, first, out);
  return out;
}

void ForwardModel::imu_packet(uint64_t sample, std::span<uint8_t, kLegacyImuPacketSize> out) const {
  const SensorClock& clock = impl_->clock;
  ImuReading reading = imu_reading(impl_->poses, clock.imu_pose_time_s(sample), impl_->sensor_from_imu);
  if (impl_->imu_errors) reading = impl_->imu_errors->apply(sample, reading);
  encode_legacy_imu(to_imu_sample(reading, clock.imu_timestamp_ns(sample)), out);
}

}  // namespace lidartwin
