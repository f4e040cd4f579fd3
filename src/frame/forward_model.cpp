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
  // One worker's buffers, so the hot loop allocates nothing: its walk along packets' columns, and
  // one column of measurements (the effect chain, column by column).
  struct Scratch {
    CastStage::Walk walk;
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
      scratch.push_back({cast.make_walk(static_cast<size_t>(f.columns_per_packet)),
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

  // Column m of frame k: from where it was observed, or not at all (outside the column window,
  // 6.4, or no pose the source stands behind). Without per-column poses every column is cast from
  // the frame's first column's pose (motion distortion left out).
  std::optional<LocatedColumn> locate_column(uint64_t frame, int m, const PoseSpan& span) const {
    const double time_s = clock.column_pose_time_s(frame, m);
    const double pose_time_s = per_column_poses ? time_s : clock.column_pose_time_s(frame, 0);
    if (!column_in_window(format().column_window, m) || !span.contains(pose_time_s)) return std::nullopt;
    return LocatedColumn{poses.at(pose_time_s), time_s - clock.pose_origin_s};
  }

  // Columns [first, last) of frame k located into columns. Returns the columns in the window that
  // had no pose.
  size_t locate_columns(uint64_t frame, int first, int last, const PoseSpan& span, FrameColumns& columns) const {
    size_t unposed = 0;
    for (int m = first; m < last; ++m) {
      const auto column = static_cast<size_t>(m);
      const std::optional<LocatedColumn> located = locate_column(frame, m, span);
      columns.observed[column] = located.has_value();
      unposed += !located && column_in_window(format().column_window, m);
      columns.times_s[column] = clock.column_pose_time_s(frame, m) - clock.pose_origin_s;
      if (located) columns.poses[column] = located->pose;
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

  // Packets [begin, end) whose columns are contiguous, in pieces of consecutive packets, a piece
  // per work item: the worker that takes a piece walks it packet by packet through the whole model
  // and hands each packet's bytes on, so packets leave in parallel with the rest of the frame's
  // casting.
  size_t render_run(uint64_t frame, size_t begin, size_t end, EncodedFrame& out, const PacketReady& ready) const {
    const int cpp = columns_per_packet();
    assert(firsts[end - 1] + cpp - firsts[begin] == static_cast<int>(end - begin) * cpp);
    assert(out.scan.width == format().columns_per_frame &&
           out.columns.poses.size() == static_cast<size_t>(out.scan.width));
    out.columns.frame_index = frame;
    const PoseSpan span = poses.span();  // one answer for the whole run: a live span may grow meanwhile
    const PacketHeader header = header_of(frame);
    const std::vector<WorkPiece> pieces = guided_pieces(static_cast<int>(end - begin), pool.size());
    std::atomic<size_t> unposed{0};
    pool.run(static_cast<int>(pieces.size()), [&](int worker, int item) {
      const WorkPiece piece = pieces[static_cast<size_t>(item)];
      const int first = firsts[begin] + piece.first * cpp;
      const size_t missed =
          render_piece(frame, first, piece.size, span, header, out, scratch[static_cast<size_t>(worker)], ready);
      unposed.fetch_add(missed, std::memory_order_relaxed);
    });
    return unposed.load();
  }

  // `count` consecutive packets from column `first`, through the forward model one after the
  // other: where each column was observed from, its timestamp and status, the cast (a packet's
  // columns together, the next packet's cast before this one's edge partners are chosen: its first
  // column is this one's neighbour), the effect chain and protocol units, the packet's bytes, then
  // ready(its index). Returns the columns in the window that had no pose.
  size_t render_piece(uint64_t frame, int first, int count, const PoseSpan& span, const PacketHeader& header,
                      EncodedFrame& out, Scratch& s, const PacketReady& ready) const {
    const int cpp = columns_per_packet();
    const ColumnLocator locate = [&](int m) { return locate_column(frame, m, span); };
    size_t unposed = 0;
    const auto prepare = [&](int begin) {
      unposed += locate_columns(frame, begin, begin + cpp, span, out.columns);
      stamp_columns(frame, begin, begin + cpp, &out.columns.observed, out.scan);
    };
    cast.walk(out.columns, first, count, cpp, locate, s.walk, prepare, [&](const CastStage::Block& block) {
      const int begin = block.begin();
      for (int m = begin; m < begin + cpp; ++m) {
        if (!out.columns.observed[static_cast<size_t>(m)]) {  // 6.4: zero pixels
          encoder.clear(m, out.scan);
          continue;
        }
        render.chain.simulate(block.column(m), cast.context(out.columns, m), s.measured);
        encoder.write(s.measured, m, out.scan);
      }
      const int index = index_of_first[static_cast<size_t>(begin / cpp)];
      packets.encode(header, out.scan, begin, slot(out, static_cast<size_t>(index)));
      if (ready) ready(static_cast<size_t>(index));
    });
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
