#pragma once
// A sensor moving along the room's x axis, and what a client sees of it: each frame's range behind
// the sensor to the west wall at x = -4 m, which tells where the sensor was when the frame began.
// Column 0 looks along the lidar frame's +x (protocol doc 6.2), which lidar_to_sensor_transform's
// default turns by 180 degrees (3.1): the sensor's -x.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "e2e/support/room.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin::e2e {

// A TUM file in the scratch directory: the sensor level at 1.5 m, x = xs[i] at times[i].
inline std::filesystem::path write_x_trajectory(const std::string& name, const std::vector<double>& times,
                                                const std::vector<double>& xs) {
  const auto path = scratch_dir() / (name + ".tum");
  std::ofstream out(path);
  for (size_t i = 0; i < times.size(); ++i) out << times[i] << " " << xs[i] << " 0 1.5 0 0 0 1\n";
  return path;
}

// The room, the trajectory, noise-free ranges (--ideal: a frame's range is a function of the pose).
inline std::vector<std::string> moving_room_args(const std::filesystem::path& trajectory) {
  return {"--profile", "os1-32", "--scene", room_scene().string(), "--trajectory", trajectory.string(),
          "--threads", "1",      "--ideal"};
}

// Where the sensor was when a frame began: the range behind less 4 m (the middle beam is within a
// degree of level; the beam origin's 15 mm and the wire's 1 mm step are below what the tests ask).
inline double x_at_frame_start(const Scan& frame) {
  const uint32_t range_mm = frame.at(ChannelField::kRange, 0, frame.height / 2);
  return range_mm * 1e-3 - 4.0;
}

struct Received {
  std::map<uint32_t, Scan> frames;                           // by frame_id, as decoded so far
  std::vector<std::pair<uint32_t, int64_t>> frame_arrivals;  // frame_id and CLOCK_MONOTONIC of its first packet
  size_t lidar_packets = 0;
  size_t imu_packets = 0;
};

// Everything that arrives for `duration`.
inline Received receive_for(UdpSocket& lidar, UdpSocket& imu, const Metadata& metadata,
                            std::chrono::milliseconds duration) {
  Received received;
  const PacketFormat format(metadata.format);
  const auto end = std::chrono::steady_clock::now() + duration;
  while (std::chrono::steady_clock::now() < end) {
    if (auto d = lidar.receive(std::chrono::milliseconds(1))) {
      ++received.lidar_packets;
      Scan packet(metadata.format);
      const auto decoded = format.decode(d->bytes, packet, nullptr);
      if (!decoded) continue;
      auto [it, fresh] = received.frames.try_emplace(decoded->header.frame_id, metadata.format);
      if (fresh) received.frame_arrivals.emplace_back(decoded->header.frame_id, d->received_ns);
      format.decode(d->bytes, it->second, nullptr);
    }
    if (auto d = imu.receive(std::chrono::milliseconds(0))) received.imu_packets += decode_legacy_imu(d->bytes) ? 1 : 0;
  }
  return received;
}

}  // namespace lidartwin::e2e
