#pragma once
// A UDP receive socket bound the way the SDK binds it (protocol doc 2.4 (c) step 1): dual-stack
// [::]:port with SO_REUSEADDR|SO_REUSEPORT and a 1 MiB receive buffer, falling back to 0.0.0.0.
// The SDK often gets less than the 1 MiB it asks for (net.core.rmem_max, item 12); as root these
// sockets force 8 MiB instead, so a test process starved by a busy 2-core host does not lose
// packets the daemon sent on time: the tests check the daemon, not the host's scheduler.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace lidartwin::e2e {

inline int64_t monotonic_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct Datagram {
  std::vector<uint8_t> bytes;
  std::string source_ip;  // IPv4 dotted (IPv4-mapped addresses unmapped)
  uint16_t source_port = 0;
  int64_t received_ns = 0;  // CLOCK_MONOTONIC when read, the daemon's INTERNAL_OSC timestamp clock
  int64_t arrived_ns = 0;   // CLOCK_REALTIME when the kernel queued it (SO_TIMESTAMPNS): unaffected
                            // by how late the receiving thread got to run
};

class UdpSocket {
 public:
  explicit UdpSocket(uint16_t port = 0) {
    fd_ = socket(AF_INET6, SOCK_DGRAM, 0);
    if (fd_ >= 0 && bind_v6(port)) return;
    if (fd_ >= 0) close(fd_);
    fd_ = socket(AF_INET, SOCK_DGRAM, 0);
    if (fd_ < 0 || !bind_v4(port)) throw std::runtime_error("cannot bind a UDP socket to port " + std::to_string(port));
  }
  ~UdpSocket() {
    if (fd_ >= 0) close(fd_);
  }
  UdpSocket(const UdpSocket&) = delete;
  UdpSocket& operator=(const UdpSocket&) = delete;

  uint16_t port() const {
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &length);
    return address.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&address)->sin6_port)
                                         : ntohs(reinterpret_cast<sockaddr_in*>(&address)->sin_port);
  }

  int fd() const { return fd_; }  // for poll() over several sockets

  std::optional<Datagram> receive(std::chrono::milliseconds timeout) {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(timeout.count())) <= 0) return std::nullopt;
    Datagram d;
    d.bytes.resize(65536);
    sockaddr_storage from{};
    iovec io{d.bytes.data(), d.bytes.size()};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec))] = {};
    msghdr message{};
    message.msg_name = &from;
    message.msg_namelen = sizeof from;
    message.msg_iov = &io;
    message.msg_iovlen = 1;
    message.msg_control = control;
    message.msg_controllen = sizeof control;
    const ssize_t n = recvmsg(fd_, &message, 0);
    d.received_ns = monotonic_now_ns();
    if (n < 0) return std::nullopt;
    d.bytes.resize(static_cast<size_t>(n));
    for (cmsghdr* c = CMSG_FIRSTHDR(&message); c; c = CMSG_NXTHDR(&message, c)) {
      if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_TIMESTAMPNS) continue;
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      d.arrived_ns = static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
    }
    set_source(from, d);
    return d;
  }

  // Drops everything queued (packets of an older config).
  void drain() {
    while (receive(std::chrono::milliseconds(0))) {
    }
  }

 private:
  void set_options() {
    const int one = 1;
    setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    setsockopt(fd_, SOL_SOCKET, SO_REUSEPORT, &one, sizeof one);
    setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one);
    const int forced = 8 << 20;
    if (setsockopt(fd_, SOL_SOCKET, SO_RCVBUFFORCE, &forced, sizeof forced) != 0) {
      const int rcvbuf = 1 << 20;
      setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    }
  }
  bool bind_v6(uint16_t port) {
    const int zero = 0;
    setsockopt(fd_, IPPROTO_IPV6, IPV6_V6ONLY, &zero, sizeof zero);
    set_options();
    sockaddr_in6 address{};
    address.sin6_family = AF_INET6;
    address.sin6_addr = in6addr_any;
    address.sin6_port = htons(port);
    return bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  }
  bool bind_v4(uint16_t port) {
    set_options();
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_ANY);
    address.sin_port = htons(port);
    return bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  }
  static void set_source(const sockaddr_storage& from, Datagram& d) {
    char text[INET6_ADDRSTRLEN] = {};
    if (from.ss_family == AF_INET) {
      const auto* v4 = reinterpret_cast<const sockaddr_in*>(&from);
      inet_ntop(AF_INET, &v4->sin_addr, text, sizeof text);
      d.source_port = ntohs(v4->sin_port);
    } else {
      const auto* v6 = reinterpret_cast<const sockaddr_in6*>(&from);
      if (IN6_IS_ADDR_V4MAPPED(&v6->sin6_addr)) {
        inet_ntop(AF_INET, &v6->sin6_addr.s6_addr[12], text, sizeof text);
      } else {
        inet_ntop(AF_INET6, &v6->sin6_addr, text, sizeof text);
      }
      d.source_port = ntohs(v6->sin6_port);
    }
    d.source_ip = text;
  }

  int fd_ = -1;
};

}  // namespace lidartwin::e2e
