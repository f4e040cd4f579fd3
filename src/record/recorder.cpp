// The frame loop of `lidartwin record`: the forward model renders and encodes frame k + 1 while
// frame k's packets, and the IMU packets due among them, are written in time order.
#include "lidartwin/record/recorder.h"

#include <array>
#include <cmath>
#include <fstream>
#include <future>
#include <vector>

#include "lidartwin/error.h"
#include "lidartwin/frame/forward_model.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/pcap/pcap.h"

namespace lidartwin {
namespace {

constexpr uint16_t kLidarPort = 7502;  // the FW defaults (protocol doc 2.6)
constexpr uint16_t kImuPort = 7503;

class CaptureWriter {
 public:
  CaptureWriter(const ForwardModel& model, const std::filesystem::path& path)
      : model_(model), pcap_(path), imu_(model.format().udp_profile_imu == UdpProfileImu::kLegacy) {}

  void write_frame(uint64_t frame, const EncodedFrame& encoded) {
    for (size_t i = 0; i < model_.packet_columns().size(); ++i) {
      write_lidar(model_.packet(encoded, i), model_.packet_timestamp_ns(frame, i));
    }
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

  const ForwardModel& model_;
  PcapWriter pcap_;
  bool imu_;
  uint64_t imu_sample_ = 0;
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

// Frame k + 1 renders while frame k is written to the capture (two buffers).
void record(const Recording& recording, const std::function<void(int frames_done)>& progress) {
  std::filesystem::create_directories(recording.out_dir);
  write_metadata(recording.metadata, recording.out_dir / "metadata.json");
  WorkerPool pool(recording.threads);
  const ForwardModel model(recording.scene, recording.poses, model_setup(recording), pool);
  CaptureWriter capture(model, recording.out_dir / "capture.pcap");
  std::array<EncodedFrame, 2> buffers{model.make_frame_buffer(), model.make_frame_buffer()};
  std::future<void> writing;
  std::vector<StampedPose> poses, column_poses;
  for (int k = 0; k < recording.frames; ++k) {
    const auto frame = static_cast<uint64_t>(k);
    EncodedFrame& encoded = buffers[frame % 2];
    model.render(frame, encoded);
    if (writing.valid()) writing.get();  // frame k - 1 written: its buffer is free again
    writing = std::async(std::launch::async, [&capture, &encoded, frame] { capture.write_frame(frame, encoded); });
    poses.push_back(frame_start_pose(model, recording.poses, frame));
    // Ground truth per column: the very pose each observed column was cast from, at the column's
    // timestamp (the packets' clock, in seconds).
    for (size_t m = 0; m < encoded.columns.observed.size(); ++m) {
      if (!encoded.columns.observed[m]) continue;
      column_poses.push_back({static_cast<double>(encoded.scan.timestamp_ns[m]) * 1e-9, encoded.columns.poses[m]});
    }
    progress(k + 1);
  }
  if (writing.valid()) writing.get();
  // And the pose where the last frame ends, so the file spans every column of the capture (compare
  // reads it as the trajectory of a record directory).
  poses.push_back(frame_start_pose(model, recording.poses, static_cast<uint64_t>(recording.frames)));
  capture.write_imu_until(model.clock().origin_ns +
                          model.clock().frame_start_ns(static_cast<uint64_t>(recording.frames)));
  write_tum(recording.out_dir / "poses.tum", poses);
  write_tum(recording.out_dir / "column_poses.tum", column_poses);
}

}  // namespace lidartwin
