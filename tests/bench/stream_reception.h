#pragma once
// What the streaming benchmarks measure at the receiving end: packets received and lost, their
// lateness against the schedule their timestamps give, the daemon's CPU use. Shared by
// stream_bench, pose_latency_bench and rig_bench.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include <linux/sock_diag.h>
#include <pthread.h>
#include <sched.h>
#include <sys/socket.h>
#include <unistd.h>

#include "../e2e/support/udp_socket.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin::bench {

using e2e::monotonic_now_ns;
using e2e::UdpSocket;

// utime + stime of a process, in seconds.
inline double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto after_name = text.rfind(')');
  std::istringstream fields(text.substr(after_name + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int index = 3; fields >> field; ++index) {
    if (index == 14) utime = std::stoull(field);
    if (index == 15) {
      stime = std::stoull(field);
      break;
    }
  }
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

struct Reception {
  size_t received = 0;
  size_t wrong_size = 0;
  size_t blank = 0;  // every column invalid (status bit 0 clear): what a daemon sends for a render stall
  std::vector<int64_t> lateness_ns;          // read by the benchmark - scheduled
  std::vector<int64_t> arrival_lateness_ns;  // queued by the kernel (SO_TIMESTAMPNS) - scheduled
  std::map<uint64_t, size_t> per_frame;      // frame_id -> packets
};

// CLOCK_REALTIME - CLOCK_MONOTONIC: kernel arrival stamps are CLOCK_REALTIME, column timestamps
// CLOCK_MONOTONIC.
inline int64_t realtime_minus_monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
             .count() -
         monotonic_now_ns();
}

// Whether any column of a packet is valid: status bit 0, in the column header (4.4) or, in LEGACY,
// the column's 4-byte footer (4.2).
inline bool any_valid_column(std::span<const uint8_t> bytes, const PacketFormat& format) {
  const auto& f = format.format();
  const bool legacy = f.udp_profile_lidar == UdpProfileLidar::kLegacy;
  for (int c = 0; c < f.columns_per_packet; ++c) {
    const size_t column = (legacy ? 0 : 32) + static_cast<size_t>(c) * format.column_size();
    const size_t status = legacy ? column + format.column_size() - 4 : column + 10;
    if (bytes[status] & 1) return true;
  }
  return false;
}

// Reads the header fields the loss and lateness figures need, straight from the bytes (4.3, 4.4;
// LEGACY 4.2): frame_id and the last column's timestamp. received_ns: CLOCK_MONOTONIC when read;
// arrived_ns: CLOCK_REALTIME when the kernel queued it.
inline void record_packet(std::span<const uint8_t> bytes, int64_t received_ns, int64_t arrived_ns,
                          const PacketFormat& format, int64_t realtime_minus_monotonic, Reception& out) {
  const auto& f = format.format();
  const bool legacy = f.udp_profile_lidar == UdpProfileLidar::kLegacy;
  const size_t header = legacy ? 0 : 32;
  const size_t last_column = header + static_cast<size_t>(f.columns_per_packet - 1) * format.column_size();
  if (bytes.size() != format.lidar_packet_size()) {
    ++out.wrong_size;
    return;
  }
  uint16_t frame_id = 0;
  uint64_t ts = 0;
  std::memcpy(&frame_id, bytes.data() + (legacy ? 10 : 2), 2);
  std::memcpy(&ts, bytes.data() + last_column, 8);
  ++out.received;
  ++out.per_frame[frame_id];
  if (!any_valid_column(bytes, format)) ++out.blank;
  out.lateness_ns.push_back(received_ns - static_cast<int64_t>(ts));
  out.arrival_lateness_ns.push_back(arrived_ns - realtime_minus_monotonic - static_cast<int64_t>(ts));
}

inline void record_packet(const e2e::Datagram& d, const PacketFormat& format, int64_t realtime_minus_monotonic,
                          Reception& out) {
  record_packet(d.bytes, d.received_ns, d.arrived_ns, format, realtime_minus_monotonic, out);
}

inline void receive(UdpSocket& socket, const PacketFormat& format, double duration_s, Reception& out) {
  const int64_t end = monotonic_now_ns() + static_cast<int64_t>(duration_s * 1e9);
  const int64_t realtime_minus_monotonic = realtime_minus_monotonic_ns();
  while (monotonic_now_ns() < end) {
    const auto d = socket.receive(std::chrono::milliseconds(200));
    if (d) record_packet(*d, format, realtime_minus_monotonic, out);
  }
}

// Reads what is queued on a socket (one of UdpSocket's: SO_TIMESTAMPNS on) up to kBatch datagrams
// a system call, into buffers kept between calls: a receiver of many streams on a host the
// daemons keep busy must not spend a system call and a fresh 64 KiB buffer on every packet, or it
// drops packets the daemons sent on time.
// Datagrams the kernel dropped at a socket so far because its receive buffer was full (SO_MEMINFO):
// losses of the receiver, not of the sender.
inline uint64_t socket_drops(int fd) {
  std::array<uint32_t, SK_MEMINFO_VARS> info{};
  socklen_t length = sizeof info;
  if (getsockopt(fd, SOL_SOCKET, SO_MEMINFO, info.data(), &length) != 0) return 0;
  return info[SK_MEMINFO_DROPS];
}

class BatchReceiver {
 public:
  BatchReceiver() : buffers_(kBatch * kSize) {}

  // Calls on_packet(bytes, received_ns, arrived_ns) for each datagram read; returns how many.
  template <class OnPacket>
  size_t drain(int fd, OnPacket&& on_packet) {
    std::array<mmsghdr, kBatch> messages{};
    std::array<iovec, kBatch> vectors{};
    for (size_t i = 0; i < kBatch; ++i) {
      vectors[i] = {buffers_.data() + i * kSize, kSize};
      messages[i].msg_hdr.msg_iov = &vectors[i];
      messages[i].msg_hdr.msg_iovlen = 1;
      messages[i].msg_hdr.msg_control = controls_[i].data();
      messages[i].msg_hdr.msg_controllen = controls_[i].size();
    }
    const int n = recvmmsg(fd, messages.data(), kBatch, MSG_DONTWAIT, nullptr);
    const int64_t received_ns = monotonic_now_ns();
    for (int i = 0; i < n; ++i) {
      const msghdr& header = messages[static_cast<size_t>(i)].msg_hdr;
      int64_t arrived_ns = 0;
      for (cmsghdr* c = CMSG_FIRSTHDR(&header); c; c = CMSG_NXTHDR(const_cast<msghdr*>(&header), c)) {
        if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_TIMESTAMPNS) continue;
        timespec ts{};
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        arrived_ns = static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
      }
      on_packet(std::span<const uint8_t>(buffers_.data() + static_cast<size_t>(i) * kSize,
                                         messages[static_cast<size_t>(i)].msg_len),
                received_ns, arrived_ns);
    }
    return n > 0 ? static_cast<size_t>(n) : 0;
  }

 private:
  static constexpr size_t kBatch = 32;
  static constexpr size_t kSize = 65536;
  std::vector<uint8_t> buffers_;
  std::array<std::array<char, CMSG_SPACE(sizeof(timespec))>, kBatch> controls_{};
};

inline double percentile_us(std::vector<int64_t> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const auto index = static_cast<size_t>(q * static_cast<double>(values.size() - 1));
  return static_cast<double>(values[index]) / 1e3;
}

// Frames seen completely inside the window (not the first or last) and their missing packets.
inline size_t lost_packets(const Reception& r, size_t expected_per_frame) {
  if (r.per_frame.size() < 3) return 0;
  size_t lost = 0;
  auto first = std::next(r.per_frame.begin());
  auto last = std::prev(r.per_frame.end());
  for (auto it = first; it != last; ++it) lost += expected_per_frame - std::min(expected_per_frame, it->second);
  // Frames missing entirely between the first and last seen.
  const uint64_t span = last->first - r.per_frame.begin()->first - 1;
  lost += (span - (r.per_frame.size() - 2)) * expected_per_frame;
  return lost;
}

// The receiver's own wake-up delay is part of what it measures; as root it runs SCHED_FIFO (like
// the daemon's send clock) so the figures show the daemon, not the benchmark's scheduling.
inline bool receive_in_real_time() {
  sched_param param{};
  param.sched_priority = 5;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
}

}  // namespace lidartwin::bench
