// The frame loop of `lidartwin record`: render + encode in the renderer's workers, then write the
// frame's packets and the IMU packets due before them, in time order.
#include "cli/recorder.h"

#include <cmath>
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

}  // namespace

void record(const Recording& recording, const std::function<void(int frames_done)>& progress) {
  const LidarDataFormat& format = recording.metadata.format;
  std::filesystem::create_directories(recording.out_dir);
  write_metadata(recording.metadata, recording.out_dir / "metadata.json");
  const PacketFormat packets(format);
  const FrameRenderer renderer(recording.scene, recording.profile, recording.chain, format, recording.render);
  CaptureWriter capture(recording, recording.out_dir / "capture.pcap");

  const std::vector<int> sent = packets_to_send(format);  // only packets meeting the window (6.4)
  const int cpp = format.columns_per_packet;
  const size_t size = packets.lidar_packet_size();
  std::vector<uint8_t> bytes(static_cast<size_t>(format.columns_per_frame / cpp) * size);
  Scan scan(format);
  std::vector<StampedPose> poses;
  for (int k = 0; k < recording.frames; ++k) {
    const auto frame = static_cast<uint64_t>(k);
    const double frame_start_s = recording.trajectory.start_s() + k / static_cast<double>(format.fps);
    const PacketHeader header = frame_header(recording.metadata, frame);
    // Each packet is encoded (with its CRC) by the worker that finished its columns.
    renderer.render(frame, frame_start_s, recording.trajectory, 0, format.columns_per_frame, scan,
                    [&](int begin, int) {
                      const auto slot = static_cast<size_t>(begin / cpp);
                      packets.encode(header, scan, begin, std::span<uint8_t>(bytes.data() + slot * size, size));
                    });
    // A packet leaves once its last column is measured (protocol doc 1, 6.1).
    for (const int first : sent) {
      const auto slot = static_cast<size_t>(first / cpp);
      capture.write_lidar({bytes.data() + slot * size, size}, scan.timestamp_ns[static_cast<size_t>(first + cpp - 1)]);
    }
    poses.push_back({frame_start_s, recording.trajectory.at(frame_start_s)});
    progress(k + 1);
  }
  capture.write_imu_until(to_ns(recording.trajectory.start_s() + recording.frames / static_cast<double>(format.fps)));
  write_tum(recording.out_dir / "poses.tum", poses);
}

}  // namespace lidartwin::cli
