// The frame loop of `lidartwin record`: the forward model renders and encodes a frame while its
// packets, the IMU packets due among them and its columns' poses are written in time order.
#include "lidartwin/record/recorder.h"

#include <array>
#include <atomic>
#include <cassert>
#include <cmath>
#include <fstream>
#include <mutex>
#include <optional>
#include <vector>

#include "lidartwin/error.h"
#include "lidartwin/frame/forward_model.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/pcap/block_file_writer.h"
#include "lidartwin/pcap/pcap.h"

namespace lidartwin {
namespace {

constexpr uint16_t kLidarPort = 7502;  // the FW defaults (protocol doc 2.6)
constexpr uint16_t kImuPort = 7503;

// Writes a frame's packets in send order while the frame renders, on the render threads: each
// worker that finishes a packet writes whatever is ready in order, if no other worker is writing.
// A writer thread of its own competed with the render threads for the cores and left one idle at
// every frame's end (pipeline_bench (d) from the drone's pose: 15-23 M pixels/s, now 24-25).
class CaptureWriter {
 public:
  // column_poses: write DIR/column_poses.tum (not for a constant pose: 20 480 identical rows per
  // 20 frames of 1024 columns say nothing poses.tum does not).
  CaptureWriter(const ForwardModel& model, const std::filesystem::path& dir, bool column_poses)
      : model_(model),
        pcap_(dir / "capture.pcap", PcapFlush::kInBlocks),
        imu_(model.format().udp_profile_imu == UdpProfileImu::kLegacy),
        ready_(model.packet_columns().size()) {
    std::filesystem::remove(dir / "column_poses.tum");  // a previous record's into the same directory
    if (column_poses) {
      column_poses_.emplace(dir / "column_poses.tum", "column poses");
      append(*column_poses_, kTumHeader);
    }
  }

  // Before frame k renders into `encoded`.
  void begin_frame(uint64_t frame, const EncodedFrame& encoded) {
    frame_ = frame;
    encoded_ = &encoded;
    next_.store(0, std::memory_order_relaxed);
    for (auto& flag : ready_) flag.store(0, std::memory_order_relaxed);
  }

  // On the worker that encoded packet `index` of the frame.
  void packet_ready(size_t index) {
    ready_[index].store(1, std::memory_order_release);
    write_ready();
  }

  // After the frame rendered: the packets no worker got to.
  void end_frame() {
    write_ready();
    assert(next_.load() == ready_.size());
  }

  void close() {
    pcap_.close();
    if (column_poses_) column_poses_->close();
  }

  // Writes the IMU packets due up to (and including) time_ns.
  void write_imu_until(uint64_t time_ns) {
    if (!imu_) return;
    for (; model_.clock().imu_timestamp_ns(imu_sample_) <= time_ns; ++imu_sample_) {
      std::array<uint8_t, kLegacyImuPacketSize> bytes{};
      model_.imu_packet(imu_sample_, bytes);
      write(bytes, model_.clock().imu_timestamp_ns(imu_sample_), kImuPort);
    }
  }

 private:
  bool next_ready() const {
    const size_t next = next_.load(std::memory_order_relaxed);
    return next < ready_.size() && ready_[next].load(std::memory_order_acquire) != 0;
  }

  // The writer re-checks after letting go, so a packet marked while it wrote does not wait for the
  // frame's end.
  void write_ready() {
    while (next_ready()) {
      const std::unique_lock lock(mutex_, std::try_to_lock);
      if (!lock.owns_lock()) return;  // the worker holding it writes this packet
      for (; next_ready(); next_.fetch_add(1, std::memory_order_relaxed)) write_packet(next_.load());
    }
  }

  // Packet `index`, then its columns' ground truth: the very pose each observed column was cast
  // from, at the column's timestamp (the packets' clock, in seconds).
  void write_packet(size_t index) {
    write_lidar(model_.packet(*encoded_, index), model_.packet_timestamp_ns(frame_, index));
    if (!column_poses_) return;
    const int first = model_.packet_columns()[index];
    for (int m = first; m < first + model_.format().columns_per_packet; ++m) {
      const auto column = static_cast<size_t>(m);
      if (!encoded_->columns.observed[column]) continue;
      const TumRow row =
          tum_row(static_cast<double>(encoded_->scan.timestamp_ns[column]) * 1e-9, encoded_->columns.poses[column]);
      append(*column_poses_, row.view());
    }
  }

  // IMU packets due up to (and including) time_ns go first, then the lidar packet.
  void write_lidar(std::span<const uint8_t> packet, uint64_t time_ns) {
    write_imu_until(time_ns);
    write(packet, time_ns, kLidarPort);
  }

  void write(std::span<const uint8_t> payload, uint64_t time_ns, uint16_t port) {
    UdpDatagramView datagram;
    datagram.timestamp_ns = time_ns;
    datagram.src_port = datagram.dst_port = port;
    datagram.payload = payload;
    pcap_.write(datagram);  // straight from the frame buffer
  }

  static void append(BlockFileWriter& file, std::string_view text) {
    file.append({reinterpret_cast<const uint8_t*>(text.data()), text.size()});
  }

  const ForwardModel& model_;
  PcapWriter pcap_;
  // A row per column: in blocks, as the capture (no page cache); none for a constant pose.
  std::optional<BlockFileWriter> column_poses_;
  bool imu_;
  uint64_t imu_sample_ = 0;
  // The frame being written: its packets' ready flags and the next one to write (in send order).
  uint64_t frame_ = 0;
  const EncodedFrame* encoded_ = nullptr;
  std::vector<std::atomic<uint8_t>> ready_;
  std::atomic<size_t> next_{0};
  std::mutex mutex_;  // held by the worker writing
};

void write_metadata(const Metadata& metadata, const std::filesystem::path& path) {
  std::ofstream out(path);
  out << to_nested_json(metadata).dump(2) << "\n";
  if (!out) throw InputError(path.string() + ": write failed");
}

ForwardModelSetup model_setup(const Recording& recording) {
  const Metadata& metadata = recording.metadata;
  ForwardModelSetup setup;
  setup.render = {metadata.beams, metadata.format, recording.max_range_m, recording.chain, recording.seed, 1.0f};
  setup.pose_origin_s = recording.poses.start_s();
  setup.origin_ns = static_cast<uint64_t>(std::llround(recording.uptime_s * 1e9));
  setup.init_id = metadata.sensor_info.initialization_id;
  setup.prod_sn = std::stoull(metadata.sensor_info.prod_sn);
  setup.imu_noise = recording.imu_noise;
  return setup;
}

// The pose at frame k's column 0, stamped with that column's timestamp (the packets' clock, s).
StampedPose frame_start_pose(const ForwardModel& model, const PoseSource& poses, uint64_t frame) {
  const SensorClock& clock = model.clock();
  return {static_cast<double>(clock.column_timestamp_ns(frame, 0)) * 1e-9,
          poses.at(clock.column_pose_time_s(frame, 0))};
}

}  // namespace

// Each frame's packets are written as they come out of the forward model (CaptureWriter).
int record(const Recording& recording, const std::function<void(int frames_done)>& progress) {
  std::filesystem::create_directories(recording.out_dir);
  write_metadata(recording.metadata, recording.out_dir / "metadata.json");
  WorkerPool pool(recording.threads);
  const ForwardModel model(recording.scene, recording.poses, model_setup(recording), pool);
  CaptureWriter capture(model, recording.out_dir, !recording.poses.constant());
  EncodedFrame encoded = model.make_frame_buffer();
  std::vector<StampedPose> poses;
  int frames = 0;  // recorded
  for (; frames < recording.frames; ++frames) {
    if (recording.stop != nullptr && recording.stop->load()) break;
    const auto frame = static_cast<uint64_t>(frames);
    capture.begin_frame(frame, encoded);
    model.render(frame, encoded, [&capture](size_t index) { capture.packet_ready(index); });
    capture.end_frame();
    poses.push_back(frame_start_pose(model, recording.poses, frame));
    progress(frames + 1);
  }
  // And the pose where the last frame ends, so the file spans every column of the capture (compare
  // reads it as the trajectory of a record directory).
  poses.push_back(frame_start_pose(model, recording.poses, static_cast<uint64_t>(frames)));
  capture.write_imu_until(model.clock().origin_ns + model.clock().frame_start_ns(static_cast<uint64_t>(frames)));
  capture.close();
  write_tum(recording.out_dir / "poses.tum", poses);
  return frames;
}

}  // namespace lidartwin
