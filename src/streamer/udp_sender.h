#pragma once
// The streamer's one UDP socket, and the optional capture of everything it sends.
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>

#include <asio.hpp>

#include "lidartwin/pcap/pcap.h"

namespace lidartwin::streamer_detail {

using Ipv4 = std::array<uint8_t, 4>;

// Bound to (source address, port 0): the datagrams leave from the sensor's own address, as the
// SDK's SensorPacketSource requires, and from an ephemeral port, never the client's port (protocol
// doc 1 item 8: a socket bound to 127.0.0.1:<client port> would capture the client's datagrams).
// Non-blocking: a full send buffer drops the datagram and counts it instead of stalling the clock.
class UdpSender {
 public:
  UdpSender(asio::io_context& io, Ipv4 source, const std::filesystem::path& record_pcap);
  UdpSender(const UdpSender&) = delete;
  UdpSender& operator=(const UdpSender&) = delete;

  bool send(Ipv4 destination, uint16_t port, std::span<const uint8_t> datagram);
  void close();
  uint64_t errors() const { return errors_; }
  // The newest failure, e.g. "to 10.0.0.2:7502: Network is unreachable" (io thread).
  const std::string& last_error() const { return last_error_; }
  uint16_t source_port() const { return source_port_; }

 private:
  void record(Ipv4 destination, uint16_t port, std::span<const uint8_t> datagram);

  asio::ip::udp::socket socket_;
  Ipv4 source_{};
  uint16_t source_port_ = 0;
  std::unique_ptr<PcapWriter> recorder_;  // null unless --record
  uint64_t errors_ = 0;
  std::string last_error_;
};

}  // namespace lidartwin::streamer_detail
