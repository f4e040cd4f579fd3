#pragma once
// The rig's ear for live poses: a UDP socket on the rig's io_context that feeds every pose message
// to LivePoses (docs/live-poses.md), and a watchdog that says in the log when the stream stalls and
// when it resumes, and what was refused and why. Nothing is dropped silently.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include <asio.hpp>

#include "lidartwin/pose/live_poses.h"

namespace lidartwin {

class PoseReceiver {
 public:
  // listen: where UDP pose messages arrive (none: HTTP only). A multicast group address (239.x.y.z)
  // joins the group on the interface with address `interface` (unspecified: the one the routing
  // table picks), so that every process of a rig spread over machines hears one vehicle's poses;
  // several processes on one host may listen to the same group and port. Throws InputError naming
  // the address if the socket cannot be bound or the group joined. `poses` must outlive the receiver.
  PoseReceiver(asio::io_context& io, LivePoses& poses, std::optional<asio::ip::udp::endpoint> listen,
               asio::ip::address_v4 interface = asio::ip::address_v4::any());
  ~PoseReceiver();
  PoseReceiver(const PoseReceiver&) = delete;
  PoseReceiver& operator=(const PoseReceiver&) = delete;

  void start();
  // On the io thread (or before it runs): closes the socket and the watchdog, so run() can return.
  void stop();
  uint16_t port() const;  // the bound UDP port (useful with port 0); 0 without UDP

 private:
  void receive_next();
  void on_datagram(size_t size);
  void arm_watchdog();
  void check_stream();
  void log_rejection(const std::string& message);

  asio::io_context& io_;
  LivePoses& poses_;
  std::optional<asio::ip::udp::socket> socket_;
  std::string joined_;  // the interface a multicast group was joined on (empty: not multicast)
  asio::ip::udp::endpoint sender_;
  std::array<uint8_t, 2048> buffer_{};
  asio::steady_timer watchdog_;
  bool stopped_ = false;
  bool stalled_ = false;
  uint64_t seen_accepted_ = 0;
  uint64_t logged_rejections_ = 0;
  uint64_t reported_rejections_ = 0;
  int64_t started_ns_ = 0;
  int64_t last_summary_ns_ = 0;
  bool waiting_logged_ = false;
};

}  // namespace lidartwin
