// The frame loop of `lidartwin record`: render + encode in the renderer's workers, then write the
// frame's packets and the IMU packets due before them, in time order.
#include "cli/recorder.h"

#include <array>
#include <cmath>
#include <future>
#include <fstream>
#include <vector>

#include "lidartwin/error.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/pcap/pcap.h"
#include "lidartwin/streamer/imu_model.h"
#include "lidartwin/streamer/packet_schedule.h"

namespace lidartwin::cli {
namespace {

constexpr uint16_t kLidarPort = 7502;  // the FW defaults (protocol doc 2.6)
constexpr uint16_t kImuPort = 7503;
constexpr double kImuPeriodS = 0.01;   // 100 Hz (5.1)

uint64_t to_ns(double time_s) { return static_cast<uint64_t>(std::llround(time_s * 1e9)); }

class CaptureWriter {
 public:
  CaptureWriter(const Recording& recording, const std::filesystem::path& path)
      : recording_(recording), pcap_(path), t0_(recording.trajectory.start_s()) {}

  // Writes IMU packets due up to (and including) time_ns, then the lidar packet.
  void write_lidar(std::span<const uint8_t> packet, uint64_t time_ns) {
    write_imu_until(time_ns);
    datagram_.timestamp_ns = time_ns;
    datagram_.src_port = datagram_.dst_port = kLidarPort;
    datagram_.payload.assign(packet.begin(), packet.end());
    pcap_.write(datagram_);
  }

  void write_imu_until(uint64_t time_ns) {
    if (recording_.metadata.format.udp_profile_imu != UdpProfileImu::kLegacy) return;
    for (;; ++imu_index_) {
      const double time_s = t0_ + static_cast<double>(imu_index_) * kImuPeriodS;
      const uint64_t stamp = to_ns(t0_) + imu_index_ * kImuPeriodNs;
      if (stamp > time_ns) return;
      std::array<uint8_t, kLegacyImuPacketSize> bytes{};
      encode_legacy_imu(imu_sample(recording_.trajectory, time_s, stamp), bytes);
      datagram_.timestamp_ns = stamp;
      datagram_.src_port = datagram_.dst_port = kImuPort;
      datagram_.payload.assign(bytes.begin(), bytes.end());
      pcap_.write(datagram_);
    }
  }

 private:
  const Recording& recording_;
  PcapWriter pcap_;
  double t0_;
  uint64_t imu_index_ = 0;
  UdpDatagram datagram_;  // reused: no allocation per packet once grown
};

PacketHeader frame_header(const Metadata& metadata, uint64_t frame) {
  PacketHeader header;
  header.frame_id = frame_id_of(frame, metadata.format);
  header.init_id = metadata.sensor_info.initialization_id;
  header.prod_sn = std::stoull(metadata.sensor_info.prod_sn);
  return header;
}

void write_metadata(const Metadata& metadata, const std::filesystem::path& path) {
  std::ofstream out(path);
  out << to_nested_json(metadata).dump(2) << "\n";
  if (!out) throw InputError(path.string() + ": write failed");
}

// One frame's sent packets, encoded, with the time each one leaves.
struct EncodedFrame {
  std::vector<uint8_t> bytes;        // packets_to_send order
  std::vector<uint64_t> times_ns;    // per packet: its last column's timestamp
};

// Renders frames and encodes their packets; each packet is encoded (with its CRC) by the render
// worker that finished its columns.
class FrameEncoder {
 public:
  explicit FrameEncoder(const Recording& recording)
      : recording_(recording),
        packets_(recording.metadata.format),
        renderer_(recording.scene, recording.profile, recording.chain, recording.metadata.format, recording.render),
        sent_(packets_to_send(recording.metadata.format)),
        scan_(recording.metadata.format) {
    const int cpp = recording.metadata.format.columns_per_packet;
    slot_of_first_.assign(static_cast<size_t>(recording.metadata.format.columns_per_frame / cpp), -1);
    for (size_t i = 0; i < sent_.size(); ++i) slot_of_first_[static_cast<size_t>(sent_[i] / cpp)] = static_cast<int>(i);
  }

  void encode(uint64_t frame, double frame_start_s, EncodedFrame& out) {
    const size_t size = packets_.lidar_packet_size();
    const int cpp = recording_.metadata.format.columns_per_packet;
    out.bytes.resize(sent_.size() * size);
    const PacketHeader header = frame_header(recording_.metadata, frame);
    renderer_.render(frame, frame_start_s, recording_.trajectory, 0, scan_.width, scan_, [&](int begin, int) {
      const int slot = slot_of_first_[static_cast<size_t>(begin / cpp)];
      if (slot < 0) return;  // no column of this packet in the window (6.4): not sent
      packets_.encode(header, scan_, begin, std::span<uint8_t>(out.bytes.data() + static_cast<size_t>(slot) * size, size));
    });
    // A packet leaves once its last column is measured (protocol doc 1, 6.1).
    out.times_ns.clear();
    for (const int first : sent_) out.times_ns.push_back(scan_.timestamp_ns[static_cast<size_t>(first + cpp - 1)]);
  }
  size_t packet_size() const { return packets_.lidar_packet_size(); }

 private:
  const Recording& recording_;
  PacketFormat packets_;
  FrameRenderer renderer_;
  std::vector<int> sent_;
  std::vector<int> slot_of_first_;  // packet index in the frame -> slot in EncodedFrame, -1 = not sent
  Scan scan_;
};

void write_frame(CaptureWriter& capture, const EncodedFrame& frame, size_t packet_size) {
  for (size_t i = 0; i < frame.times_ns.size(); ++i) {
    capture.write_lidar({frame.bytes.data() + i * packet_size, packet_size}, frame.times_ns[i]);
  }
}

}  // namespace

// Frame k + 1 renders while frame k is written to the capture (two buffers).
void record(const Recording& recording, const std::function<void(int frames_done)>& progress) {
  const LidarDataFormat& format = recording.metadata.format;
  std::filesystem::create_directories(recording.out_dir);
  write_metadata(recording.metadata, recording.out_dir / "metadata.json");
  FrameEncoder encoder(recording);
  CaptureWriter capture(recording, recording.out_dir / "capture.pcap");
  std::array<EncodedFrame, 2> buffers;
  std::future<void> writing;
  std::vector<StampedPose> poses;
  for (int k = 0; k < recording.frames; ++k) {
    const double frame_start_s = recording.trajectory.start_s() + k / static_cast<double>(format.fps);
    EncodedFrame& frame = buffers[static_cast<size_t>(k % 2)];
    encoder.encode(static_cast<uint64_t>(k), frame_start_s, frame);
    if (writing.valid()) writing.get();  // frame k - 1 written: its buffer is free again
    writing = std::async(std::launch::async, [&capture, &frame, &encoder] { write_frame(capture, frame, encoder.packet_size()); });
    poses.push_back({frame_start_s, recording.trajectory.at(frame_start_s)});
    progress(k + 1);
  }
  if (writing.valid()) writing.get();
  capture.write_imu_until(to_ns(recording.trajectory.start_s() + recording.frames / static_cast<double>(format.fps)));
  write_tum(recording.out_dir / "poses.tum", poses);
}

}  // namespace lidartwin::cli
