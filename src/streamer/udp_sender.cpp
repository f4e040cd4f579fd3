#include "streamer/udp_sender.h"

#include <chrono>

#include <spdlog/spdlog.h>

#include "lidartwin/error.h"

namespace lidartwin::streamer_detail {

namespace {
// Room for several frames of the largest packets: the send clock must never block on the kernel.
constexpr int kSendBufferBytes = 8 * 1024 * 1024;

asio::ip::address_v4 to_address(Ipv4 ip) { return asio::ip::address_v4(ip); }

uint64_t wall_clock_ns() {
  return static_cast<uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}
}  // namespace

UdpSender::UdpSender(asio::io_context& io, Ipv4 source, const std::filesystem::path& record_pcap)
    : socket_(io), source_(source) {
  asio::error_code error;
  socket_.open(asio::ip::udp::v4(), error);
  if (!error) socket_.bind(asio::ip::udp::endpoint(to_address(source), 0), error);
  if (error) {
    throw InputError("cannot bind the UDP sending socket to " + to_address(source).to_string() + ": " +
                     error.message() + " (is --address an address of this host?)");
  }
  socket_.set_option(asio::socket_base::send_buffer_size(kSendBufferBytes), error);
  socket_.non_blocking(true, error);
  source_port_ = socket_.local_endpoint(error).port();
  if (!record_pcap.empty()) recorder_ = std::make_unique<PcapWriter>(record_pcap);
}

bool UdpSender::send(Ipv4 destination, uint16_t port, std::span<const uint8_t> datagram) {
  asio::error_code error;
  socket_.send_to(asio::buffer(datagram.data(), datagram.size()),
                  asio::ip::udp::endpoint(to_address(destination), port), 0, error);
  if (error) {
    // Logged by the caller's rate-limited stats line; one line per datagram would flood the log. A
    // destination that is gone (ENETUNREACH, EHOSTUNREACH) or refuses (ECONNREFUSED after an ICMP
    // port unreachable) costs this datagram only: the next one is tried as if nothing happened.
    ++errors_;
    last_error_ = "to " + to_address(destination).to_string() + ":" + std::to_string(port) + ": " + error.message();
    return false;
  }
  if (recorder_) record(destination, port, datagram);
  return true;
}

// A recording that fails (the disk filled) ends there, and the stream goes on: a HIL rig's sensor
// must not die because its capture could not be kept. What was written stays readable (a pcap
// reader ends at a record cut short).
void UdpSender::record(Ipv4 destination, uint16_t port, std::span<const uint8_t> datagram) {
  try {
    recorder_->write(UdpDatagramView{wall_clock_ns(), source_, destination, source_port_, port, datagram});
  } catch (const InputError& e) {
    spdlog::error("streamer: --record: {}; recording stopped, streaming goes on", e.what());
    try {
      recorder_->close();
    } catch (const InputError&) {  // the same failure, said once
    }
    recorder_.reset();
  }
}

void UdpSender::close() {
  asio::error_code ignored;
  socket_.close(ignored);
}

}  // namespace lidartwin::streamer_detail
