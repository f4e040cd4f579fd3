// Live-pose latency benchmark: starts the real daemon with live poses (UDP, CLOCK_MONOTONIC),
// flies the plant inspection loop by sending its poses at --rate Hz as a HIL rig would, receives
// the lidar stream, and prints for each mode
//   - the latency from a pose's arrival to the first packet cast with it (the daemon's p50/p99/max,
//     GET /lidartwin/v1/pose), target p99 <= 2 ms at 1024x10 (issue 25), and how many packets were
//     cast a second time for it,
//   - whether real time held: lidar packets lost, arrival lateness p99 (kernel stamp - schedule),
//     render stalls and columns that had no pose,
//   - the daemon's CPU use.
//   pose_latency_bench [--duration 20] [--profile os1-64] [--modes 1024x10,2048x10] [--rate 100]
//                      [--cast-ahead-ms 5] [--threads 0]
#include <atomic>
#include <cstdio>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include "../e2e/support/daemon.h"
#include "../e2e/support/pose_sender.h"
#include "../e2e/support/sdk_client.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_message.h"
#include "stream_reception.h"

namespace {
using namespace lidartwin;
using namespace lidartwin::e2e;
using namespace lidartwin::bench;

struct Flags {
  double duration_s = 20;
  std::string profile = "os1-64";
  std::vector<std::string> modes{"1024x10", "2048x10"};
  double rate_hz = 100;
  std::string cast_ahead_ms = "5";
  std::string threads = "0";
};

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  for (std::string part; std::getline(in, part, ',');) parts.push_back(part);
  return parts;
}

Flags parse_flags(int argc, char** argv) {
  Flags flags;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--duration") flags.duration_s = std::stod(value);
    else if (key == "--profile") flags.profile = value;
    else if (key == "--modes") flags.modes = split(value);
    else if (key == "--rate") flags.rate_hz = std::stod(value);
    else if (key == "--cast-ahead-ms") flags.cast_ahead_ms = value;
    else if (key == "--threads") flags.threads = value;
    else throw std::runtime_error("unknown flag " + key);
  }
  return flags;
}

// The rig: the inspection loop's poses at rate_hz, stamped with CLOCK_MONOTONIC when sent.
class Rig {
 public:
  Rig(uint16_t port, double rate_hz)
      : trajectory_(Trajectory::load_tum(std::string(LIDARTWIN_SOURCE_DIR) + "/scenes/plant_inspection.tum")),
        sender_("127.0.0.1", port),
        thread_([this, rate_hz] { run(rate_hz); }) {}
  ~Rig() {
    stop_ = true;
    thread_.join();
  }

 private:
  void run(double rate_hz) {
    const auto period = std::chrono::nanoseconds(static_cast<int64_t>(1e9 / rate_hz));
    const int64_t start = monotonic_now_ns();
    auto next = std::chrono::steady_clock::now();
    for (uint32_t sequence = 1; !stop_; ++sequence) {
      PoseMessage message;
      message.sequence = sequence;
      message.time_ns = monotonic_now_ns();
      message.pose = trajectory_.at(trajectory_.start_s() + static_cast<double>(message.time_ns - start) * 1e-9);
      const auto bytes = encode_pose_message(message);
      sender_.send(std::vector<uint8_t>(bytes.begin(), bytes.end()));
      next += period;
      std::this_thread::sleep_until(next);
    }
  }

  Trajectory trajectory_;
  PoseSender sender_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

int run_mode(const Flags& flags, const std::string& mode) {
  UdpSocket lidar;
  Daemon daemon("127.0.0.1", 0,
                {"--profile", flags.profile, "--threads", flags.threads, "--pose-udp", "127.0.0.1:0", "--pose-clock",
                 "monotonic", "--cast-ahead-ms", flags.cast_ahead_ms},
                std::chrono::seconds(120));
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_mode = mode;
  request.lidar_port = lidar.port();
  const Metadata metadata = parse_metadata(sdk016_init_client(http, request), "GET sensor/metadata");
  const PacketFormat format(metadata.format);
  Reception reception;
  nlohmann::json status;
  double cpu = 0;
  {
    Rig rig(pose_udp_port(daemon.log()), flags.rate_hz);
    std::this_thread::sleep_for(std::chrono::milliseconds(1000));  // poses flowing, stream settled
    lidar.drain();
    const nlohmann::json before = nlohmann::json::parse(http.raw_get("/lidartwin/v1/pose")->body);
    const uint64_t stalls_before = http.get_json("sensor/telemetry")["lidartwin"]["render_stalls"].get<uint64_t>();
    const double cpu_before = cpu_seconds(daemon.pid());
    const int64_t wall_before = monotonic_now_ns();
    receive(lidar, format, flags.duration_s, reception);
    cpu = (cpu_seconds(daemon.pid()) - cpu_before) / (static_cast<double>(monotonic_now_ns() - wall_before) * 1e-9);
    status = nlohmann::json::parse(http.raw_get("/lidartwin/v1/pose")->body);
    status["columns_without_pose_during"] =
        status["columns_without_pose"].get<uint64_t>() - before["columns_without_pose"].get<uint64_t>();
    status["recast_packets_during"] =
        status["recast_packets"].get<uint64_t>() - before["recast_packets"].get<uint64_t>();
    // The telemetry is refreshed once a second: wait for the figures of the measured interval.
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));
    status["render_stalls_during"] =
        http.get_json("sensor/telemetry")["lidartwin"]["render_stalls"].get<uint64_t>() - stalls_before;
  }
  const int code = daemon.stop();
  const auto& latency = status["latency"];
  const size_t per_frame = static_cast<size_t>(format.packets_per_frame());
  std::printf("pose_latency_bench: %s %s, poses at %.0f Hz, cast ahead %s ms, %.0f s\n", flags.profile.c_str(),
              mode.c_str(), flags.rate_hz, flags.cast_ahead_ms.c_str(), flags.duration_s);
  std::printf("  pose arrival -> first packet cast with it: p50 %.2f ms, p99 %.2f ms, max %.2f ms (%llu poses)\n",
              latency["p50_us"].get<double>() / 1e3, latency["p99_us"].get<double>() / 1e3,
              latency["max_us"].get<double>() / 1e3, latency["count"].get<unsigned long long>());
  std::printf("  real time: received %zu lidar packets, lost %zu; arrival lateness p99 %.1f us, max %.1f us\n",
              reception.received, lost_packets(reception, per_frame),
              percentile_us(reception.arrival_lateness_ns, 0.99), percentile_us(reception.arrival_lateness_ns, 1.0));
  std::printf("  while measuring: render stalls %llu, columns without a pose %llu; poses accepted %llu, refused %llu\n",
              status["render_stalls_during"].get<unsigned long long>(),
              status["columns_without_pose_during"].get<unsigned long long>(),
              status["accepted"].get<unsigned long long>(), status["rejected_total"].get<unsigned long long>());
  std::printf("  packets cast again with a pose that arrived after their first cast: %llu of %zu\n",
              status["recast_packets_during"].get<unsigned long long>(), reception.received);
  std::printf("  daemon CPU: %.0f %% of one core; exit code %d\n", cpu * 100.0, code);
  return code == 0 ? 0 : 1;
}
}  // namespace

int main(int argc, char** argv) {
  try {
    const Flags flags = parse_flags(argc, argv);
    int result = 0;
    for (const std::string& mode : flags.modes) result |= run_mode(flags, mode);
    return result;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pose_latency_bench: %s\n", e.what());
    return 1;
  }
}
