// Streaming benchmark: starts the real daemon (OS1-128, 2048x10, the plant scene by default),
// configures it like SDK-0.16 init_client, receives for --duration seconds and prints
//   - lidar packets lost (gaps in frame_id x packet slot),
//   - lateness p50/p99/max = arrival time - the packet's scheduled time, twice: as the kernel
//     stamped the datagram into the socket (SO_TIMESTAMPNS: the daemon's doing) and as the
//     benchmark read it (adds the benchmark's own wake-up). The
//     scheduled time is the timestamp of the packet's last column: in TIME_FROM_INTERNAL_OSC the
//     daemon stamps columns with CLOCK_MONOTONIC and sends each packet when its last column's time
//     has come (see streamer.h), so this is send lateness plus loopback delivery,
//   - the daemon's own send-lateness summary (its "streamer: stopped" log line),
//   - the daemon's CPU use from /proc/<pid>/stat.
// Targets: 0 lost, p99 <= 200 us.
//   stream_bench [--duration 30] [--profile os1-128] [--mode 2048x10] [--udp-profile P]
//                [--scene S --pose "x y z qx qy qz qw"] [--threads N]
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include "../e2e/support/daemon.h"
#include "../e2e/support/sdk_client.h"
#include "../e2e/support/udp_socket.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/lidar_packet.h"

namespace {
using namespace lidartwin;
using namespace lidartwin::e2e;

struct Flags {
  double duration_s = 30;
  std::string profile = "os1-128";
  std::string mode = "2048x10";
  std::string udp_profile = "RNG19_RFL8_SIG16_NIR16";
  std::string scene;
  std::string pose;
  std::string threads = "0";
};

Flags parse_flags(int argc, char** argv) {
  Flags flags;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--duration") flags.duration_s = std::stod(value);
    else if (key == "--profile") flags.profile = value;
    else if (key == "--mode") flags.mode = value;
    else if (key == "--udp-profile") flags.udp_profile = value;
    else if (key == "--scene") flags.scene = value;
    else if (key == "--pose") flags.pose = value;
    else if (key == "--threads") flags.threads = value;
    else throw std::runtime_error("unknown flag " + key);
  }
  return flags;
}

// utime + stime of a process, in seconds.
double cpu_seconds(pid_t pid) {
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
  std::vector<int64_t> lateness_ns;          // read by the benchmark - scheduled
  std::vector<int64_t> arrival_lateness_ns;  // queued by the kernel (SO_TIMESTAMPNS) - scheduled
  std::map<uint64_t, size_t> per_frame;      // frame_id -> packets
};

// Reads the header fields the loss and lateness figures need, straight from the bytes (4.3, 4.4;
// LEGACY 4.2): frame_id and the last column's timestamp.
void receive(UdpSocket& socket, const PacketFormat& format, double duration_s, Reception& out) {
  const auto& f = format.format();
  const bool legacy = f.udp_profile_lidar == UdpProfileLidar::kLegacy;
  const size_t header = legacy ? 0 : 32;
  const size_t last_column = header + static_cast<size_t>(f.columns_per_packet - 1) * format.column_size();
  const int64_t end = monotonic_now_ns() + static_cast<int64_t>(duration_s * 1e9);
  // Kernel arrival stamps are CLOCK_REALTIME; column timestamps are CLOCK_MONOTONIC.
  const int64_t realtime_minus_monotonic =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count() -
      monotonic_now_ns();
  while (monotonic_now_ns() < end) {
    const auto d = socket.receive(std::chrono::milliseconds(200));
    if (!d) continue;
    if (d->bytes.size() != format.lidar_packet_size()) {
      ++out.wrong_size;
      continue;
    }
    uint16_t frame_id = 0;
    uint64_t ts = 0;
    std::memcpy(&frame_id, d->bytes.data() + (legacy ? 10 : 2), 2);
    std::memcpy(&ts, d->bytes.data() + last_column, 8);
    ++out.received;
    ++out.per_frame[frame_id];
    out.lateness_ns.push_back(d->received_ns - static_cast<int64_t>(ts));
    out.arrival_lateness_ns.push_back(d->arrived_ns - realtime_minus_monotonic - static_cast<int64_t>(ts));
  }
}

double percentile_us(std::vector<int64_t> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const auto index = static_cast<size_t>(q * static_cast<double>(values.size() - 1));
  return static_cast<double>(values[index]) / 1e3;
}

std::vector<std::string> daemon_args(const Flags& flags) {
  std::vector<std::string> args{"--profile", flags.profile, "--threads", flags.threads};
  if (!flags.scene.empty()) args.insert(args.end(), {"--scene", flags.scene});
  if (!flags.pose.empty()) args.insert(args.end(), {"--pose", flags.pose});
  return args;
}

// Frames seen completely inside the window (not the first or last) and their missing packets.
size_t lost_packets(const Reception& r, size_t expected_per_frame) {
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
bool receive_in_real_time() {
  sched_param param{};
  param.sched_priority = 5;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
}

int run(const Flags& flags) {
  UdpSocket lidar;
  UdpSocket imu;
  Daemon daemon("127.0.0.1", 0, daemon_args(flags), std::chrono::seconds(120));
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_mode = flags.mode;
  request.udp_profile_lidar = flags.udp_profile;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  const Metadata metadata = parse_metadata(sdk016_init_client(http, request), "GET sensor/metadata");
  const PacketFormat format(metadata.format);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let the stream settle
  lidar.drain();

  const bool realtime = receive_in_real_time();
  const double cpu_before = cpu_seconds(daemon.pid());
  const int64_t wall_before = monotonic_now_ns();
  Reception reception;
  std::thread imu_drain([&imu, &flags] {
    const int64_t end = monotonic_now_ns() + static_cast<int64_t>(flags.duration_s * 1e9);
    while (monotonic_now_ns() < end) imu.receive(std::chrono::milliseconds(200));
  });
  receive(lidar, format, flags.duration_s, reception);
  imu_drain.join();
  const double cpu =
      (cpu_seconds(daemon.pid()) - cpu_before) / (static_cast<double>(monotonic_now_ns() - wall_before) * 1e-9);
  const int code = daemon.stop();

  const size_t per_frame = static_cast<size_t>(format.packets_per_frame());
  std::printf("stream_bench: %s %s %s, %.0f s, %zu B packets, %zu per frame\n", flags.profile.c_str(),
              flags.mode.c_str(), flags.udp_profile.c_str(), flags.duration_s, format.lidar_packet_size(), per_frame);
  std::printf("  received %zu lidar packets, lost %zu, wrong size %zu\n", reception.received,
              lost_packets(reception, per_frame), reception.wrong_size);
  std::printf("  arrival lateness (kernel stamp - schedule): p50 %.1f us, p99 %.1f us, max %.1f us\n",
              percentile_us(reception.arrival_lateness_ns, 0.5), percentile_us(reception.arrival_lateness_ns, 0.99),
              percentile_us(reception.arrival_lateness_ns, 1.0));
  std::printf("  receive lateness (read - schedule):          p50 %.1f us, p99 %.1f us, max %.1f us\n",
              percentile_us(reception.lateness_ns, 0.5), percentile_us(reception.lateness_ns, 0.99),
              percentile_us(reception.lateness_ns, 1.0));
  std::printf("  receiver %s\n", realtime ? "SCHED_FIFO" : "at normal priority");
  std::printf("  daemon CPU: %.0f %% of one core\n", cpu * 100.0);
  std::smatch line;
  const std::string log = daemon.log();
  if (std::regex_search(log, line, std::regex("streamer: stopped after[^\n]*")))
    std::printf("  daemon: %s\n", line.str().c_str());
  std::smatch warnings;
  if (std::regex_search(log, warnings, std::regex("(warn|error)[^\n]*")))
    std::printf("  daemon log: %s\n", warnings.str().c_str());
  std::printf("  daemon exit code %d\n", code);
  return code == 0 ? 0 : 1;
}
}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse_flags(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stream_bench: %s\n", e.what());
    return 1;
  }
}
