#pragma once
// A HIL rig's side of live poses: pose messages laid out byte by byte from the table in
// docs/live-poses.md (not with the daemon's encoder), sent over UDP as a simulator would.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "e2e/support/log_port.h"

namespace lidartwin::e2e {

struct RigPose {
  uint32_t sequence = 0;
  int64_t time_ns = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

inline std::vector<uint8_t> pose_datagram(const RigPose& pose, uint16_t version = 1) {
  std::vector<uint8_t> bytes(128, 0);
  const auto put = [&bytes](size_t offset, auto value) { std::memcpy(bytes.data() + offset, &value, sizeof value); };
  std::memcpy(bytes.data(), "LTPS", 4);
  put(4, version);
  put(6, uint16_t{0});
  put(8, pose.sequence);
  put(16, pose.time_ns);
  for (int i = 0; i < 3; ++i) put(24 + 8 * static_cast<size_t>(i), pose.position[i]);
  const std::array<double, 4> q{pose.orientation.x(), pose.orientation.y(), pose.orientation.z(), pose.orientation.w()};
  for (size_t i = 0; i < 4; ++i) put(48 + 8 * i, q[i]);
  return bytes;
}

class PoseSender {
 public:
  PoseSender(const std::string& address, uint16_t port) : fd_(socket(AF_INET, SOCK_DGRAM, 0)) {
    to_.sin_family = AF_INET;
    to_.sin_port = htons(port);
    inet_pton(AF_INET, address.c_str(), &to_.sin_addr);
  }
  ~PoseSender() { close(fd_); }
  PoseSender(const PoseSender&) = delete;
  PoseSender& operator=(const PoseSender&) = delete;

  void send(const std::vector<uint8_t>& bytes) const {
    sendto(fd_, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to_), sizeof to_);
  }

 private:
  int fd_;
  sockaddr_in to_{};
};

// The UDP port the daemon listens on for poses, from its log line.
inline uint16_t pose_udp_port(const std::string& log) {
  const std::optional<int> port = port_after(log, "live poses: listening on udp ");
  if (!port) throw std::runtime_error("no pose listening line in the log:\n" + log);
  return static_cast<uint16_t>(*port);
}

}  // namespace lidartwin::e2e
