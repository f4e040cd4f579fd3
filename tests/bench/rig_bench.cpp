// Rig benchmark (issue 26): how many OS1-64 1024x10 sensors this machine streams in real time in
// the plant (serve's defaults: scenes/plant.glb and the drone's inspection lap), as one
// `serve --rig` process and as as many separate `serve` daemons. For each count and mode it starts
// the daemon(s), configures every sensor as SDK 0.16's init_client does (each its own UDP ports),
// receives every stream for --duration seconds and prints one row:
//   - stalls: packets that arrived with every column invalid, as the daemon sends a packet whose
//     columns were not rendered in time (a render stall), and how they spread over the sensors
//     (the least and the most stalled sensor's share of its packets, %);
//   - lost: lidar packets missing at the receiver (frame_id x packet gaps; what the send clock
//     skipped shows here too), less those the receiving sockets dropped for a full buffer
//     (SO_MEMINFO), which are the benchmark's own and printed beside;
//   - send lateness p99 of the worst sensor, as the daemon reports it ("streamer ... stopped" log
//     line: its whole run, the configuring included), and beside it as the kernel stamped each
//     packet's arrival in the window (loopback: send lateness plus delivery);
//   - CPU (cores) and RSS per sensor of the daemon processes over the window;
//   - the rendered pixel rate of all sensors together, and its ratio to (a'): raw Embree casting
//     this sensor's rays over the same lap, packed as the caster packs them, on all cores
//     (raw_embree.h), measured first.
// A row passes with no stall, no loss and p99 under 1 ms; the largest passing count of each mode
// is printed last. The machine's other load (CPU of every process but these, over the window) is
// printed with each row: the figures compare only on an otherwise idle machine.
//   rig_bench [--duration 15] [--counts 1,2,4,8,16,32] [--max-sensors 32] [--modes rig,daemons]
//             [--serve-args "--spin-us 0 ..."] [--settle 2]
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

// Eigen before httplib: <resolv.h>, which httplib includes, defines _res, a name Eigen's headers use.
#include "lidartwin/frame/forward_model.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/profile/sensor_profile.h"
#include "raw_embree.h"

#include "../e2e/support/daemon.h"
#include "../e2e/support/sdk_client.h"
#include "../e2e/support/udp_socket.h"
#include "stream_reception.h"

namespace {
using namespace lidartwin;
using namespace lidartwin::e2e;
using namespace lidartwin::bench;

const std::filesystem::path kSource = LIDARTWIN_SOURCE_DIR;
constexpr const char* kProfile = "os1-64";
constexpr const char* kMode = "1024x10";
constexpr const char* kUdpProfile = "RNG19_RFL8_SIG16_NIR16";

struct Flags {
  double duration_s = 15;
  double settle_s = 2;  // after the last sensor is configured, before the window
  std::vector<int> counts{1, 2, 4, 8, 16, 32};
  int max_sensors = 32;
  std::vector<std::string> modes{"rig", "daemons"};
  std::vector<std::string> serve_args;  // passed to every serve
};

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  for (std::string part; std::getline(in, part, separator);)
    if (!part.empty()) parts.push_back(part);
  return parts;
}

Flags parse_flags(int argc, char** argv) {
  Flags flags;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--duration") flags.duration_s = std::stod(value);
    else if (key == "--settle") flags.settle_s = std::stod(value);
    else if (key == "--max-sensors") flags.max_sensors = std::stoi(value);
    else if (key == "--modes") flags.modes = split(value, ',');
    else if (key == "--serve-args") flags.serve_args = split(value, ' ');
    else if (key == "--counts") {
      flags.counts.clear();
      for (const std::string& count : split(value, ',')) flags.counts.push_back(std::stoi(count));
    } else throw std::runtime_error("unknown flag " + key);
  }
  if (argc % 2 == 0) throw std::runtime_error(std::string("flag without a value: ") + argv[argc - 1]);
  return flags;
}

// ---- (a'): raw Embree on an OS1-64 1024x10's rays over the drone's lap --------------------------

// Rays per second, the best of three, on all cores. The frames are spread over the lap's first
// 20 s (one a second), the stretch the streams of a run cover.
double measure_a_prime() {
  const Scene scene = Scene::load(kSource / "scenes/plant.glb");
  const SensorProfile profile = load_profile(kProfile);
  SensorInfo info;
  info.prod_sn = "992200000001";
  info.initialization_id = 1;
  nlohmann::json config = default_config_params();
  config["lidar_mode"] = kMode;
  config["udp_profile_lidar"] = kUdpProfile;
  const Metadata metadata = make_metadata(info, profile.beams, config);
  const TrajectoryPoses poses(Trajectory::load_tum(kSource / "scenes/plant_inspection.tum"));
  WorkerPool pool(1);
  ForwardModelSetup setup;
  setup.render = {metadata.beams, metadata.format, profile.max_range_m, EffectChain(), 1, 1.0f};
  const ForwardModel model(scene, poses, setup, pool);  // for the cast range the daemon uses
  const auto rays =
      prebuilt_rays(metadata.beams, metadata.format, poses, {20, 1.0}, model.cast_range_m(), Packing::kCasterStrips);
  const int threads = static_cast<int>(std::thread::hardware_concurrency());
  double best = 0;
  for (int repeat = 0; repeat < 3; ++repeat)
    best = std::max(best, raw_packets(scene, metadata.format.pixels_per_column, rays, threads).wall_per_s);
  return best;
}

// ---- the host ---------------------------------------------------------------------------------

long rss_kib(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return 0;
}

// CPU seconds every process of the machine has used (/proc/stat: all but idle and iowait).
double machine_cpu_seconds() {
  std::ifstream in("/proc/stat");
  std::string cpu;
  unsigned long long user = 0, nice = 0, system = 0, idle = 0, iowait = 0, irq = 0, softirq = 0, steal = 0;
  in >> cpu >> user >> nice >> system >> idle >> iowait >> irq >> softirq >> steal;
  return static_cast<double>(user + nice + system + irq + softirq) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string one, five;
  in >> one >> five;
  return one + " " + five;
}

// ---- one run: N sensors in one mode ------------------------------------------------------------

struct Stream {
  std::string address;
  int http_port = 0;
  std::unique_ptr<UdpSocket> lidar = std::make_unique<UdpSocket>();
  std::unique_ptr<UdpSocket> imu = std::make_unique<UdpSocket>();
  std::optional<PacketFormat> format;
  Reception reception;
  uint64_t drops = 0;  // by the lidar socket in the window (a full buffer)
};

struct Row {
  int sensors = 0;
  std::string mode;
  std::string error;  // the run could not be measured
  uint64_t stalls = 0;
  double fewest_stalls = 0;  // % of one sensor's packets: the least stalled sensor's
  double most_stalls = 0;    // and the most stalled one's
  uint64_t lost = 0;         // by the daemon: missing at the receiver, less its own drops
  uint64_t rx_drops = 0;     // by the receiving sockets, buffer full
  double p99_daemon_us = 0;
  double p99_arrival_us = 0;
  double cores = 0;
  double rss_mib = 0;  // all daemon processes
  double pixels_per_s = 0;
  double other_cores = 0;  // every other process of the machine, this benchmark included
  std::string load;
  bool passes() const { return error.empty() && stalls == 0 && lost == 0 && p99_daemon_us < 1000.0; }
};

std::string address_of(int index) { return "127.0.0." + std::to_string(index + 2); }

std::filesystem::path write_rig_file(int sensors) {
  nlohmann::json entries = nlohmann::json::array();
  for (int i = 0; i < sensors; ++i) {
    entries.push_back({{"name", "s" + std::to_string(i + 1)},
                       {"profile", kProfile},
                       {"address", address_of(i)},
                       {"lidar_mode", kMode},
                       {"udp_profile", kUdpProfile}});
  }
  const auto file = scratch_dir() / ("rig_bench_" + std::to_string(sensors) + ".json");
  std::ofstream(file) << nlohmann::json{{"description", "rig_bench"}, {"sensors", entries}}.dump(2) << "\n";
  return file;
}

// Each sensor's HTTP port from a daemon's "answering on http://ADDRESS:PORT/" lines.
std::map<std::string, int> answering_ports(const std::string& log) {
  std::map<std::string, int> ports;
  const std::regex line("answering on http://([0-9.]+):([0-9]+)/");
  for (std::sregex_iterator it(log.begin(), log.end(), line), end; it != end; ++it)
    ports[(*it)[1].str()] = std::stoi((*it)[2].str());
  return ports;
}

// Calls work(i) for every sensor on a thread of its own; rethrows the first exception.
void for_each_sensor(int sensors, const std::function<void(int)>& work) {
  std::vector<std::exception_ptr> errors(static_cast<size_t>(sensors));
  {
    std::vector<std::jthread> threads;
    for (int i = 0; i < sensors; ++i) {
      threads.emplace_back([&, i] {
        try {
          work(i);
        } catch (...) {
          errors[static_cast<size_t>(i)] = std::current_exception();
        }
      });
    }
  }
  for (const auto& error : errors)
    if (error) std::rethrow_exception(error);
}

std::vector<std::unique_ptr<Daemon>> start_daemons(const std::string& mode, int sensors,
                                                   const std::vector<std::string>& serve_args) {
  std::vector<std::unique_ptr<Daemon>> daemons;
  if (mode == "rig") {
    std::vector<std::string> args{"--rig", write_rig_file(sensors).string(), "--http-port", "0"};
    args.insert(args.end(), serve_args.begin(), serve_args.end());
    daemons.push_back(
        std::make_unique<Daemon>(Daemon::Rig{}, address_of(sensors - 1), args, std::chrono::seconds(120)));
    return daemons;
  }
  std::vector<std::string> args{"--profile", kProfile, "--lidar-mode", kMode, "--udp-profile", kUdpProfile};
  args.insert(args.end(), serve_args.begin(), serve_args.end());
  // Started side by side: on a busy host each takes seconds to load the scene.
  daemons.resize(static_cast<size_t>(sensors));
  for_each_sensor(sensors, [&](int i) {
    daemons[static_cast<size_t>(i)] = std::make_unique<Daemon>(address_of(i), 0, args, std::chrono::seconds(120));
  });
  return daemons;
}

// As SDK 0.16's init_client, tried three times: on a host with more daemons than it can serve, an
// HTTP answer may take longer than the client's 4 s time-out (noted on stderr).
void configure(Stream& stream) {
  ConfigRequest request;
  request.lidar_mode = kMode;
  request.udp_profile_lidar = kUdpProfile;
  request.lidar_port = stream.lidar->port();
  request.imu_port = stream.imu->port();
  for (int attempt = 1;; ++attempt) {
    try {
      SensorHttp http(stream.address, stream.http_port);
      const Metadata metadata = parse_metadata(sdk016_init_client(http, request), "GET sensor/metadata");
      stream.format.emplace(metadata.format);
      return;
    } catch (const std::exception& e) {
      if (attempt == 3) throw;
      std::fprintf(stderr, "rig_bench: configuring %s, attempt %d: %s\n", stream.address.c_str(), attempt, e.what());
    }
  }
}

// Every lidar and IMU socket, from one thread; IMU packets are only drained.
class StreamsReceiver {
 public:
  // The receiver stands in for clients on other machines: given a fair share of two cores beside
  // a dozen daemons (even at nice -10) it fell more than a receive buffer behind and counted
  // thousands of losses the daemons had not caused (their logs: 0 skipped). As root it runs
  // SCHED_FIFO below the daemons' send clocks, as stream_bench's does; else at nice -10.
  explicit StreamsReceiver(std::vector<Stream>& streams) : streams_(streams) {
    if (!receive_in_real_time()) setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), -10);
    for (const Stream& s : streams) {
      fds_.push_back({s.lidar->fd(), POLLIN, 0});
      fds_.push_back({s.imu->fd(), POLLIN, 0});
    }
  }
  // Back to the normal policy: the daemons of the next run are forked from this thread.
  ~StreamsReceiver() {
    const sched_param normal{};
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
    setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 0);
  }
  StreamsReceiver(const StreamsReceiver&) = delete;
  StreamsReceiver& operator=(const StreamsReceiver&) = delete;

  // Empties every socket, so that the window starts with nothing queued from before it, and
  // starts counting each lidar socket's drops (a full buffer) from here.
  void open_window() {
    const auto discard = [](std::span<const uint8_t>, int64_t, int64_t) {};
    for (bool any = true; any;) {
      any = false;
      for (const pollfd& p : fds_) any = receiver_.drain(p.fd, discard) > 0 || any;
    }
    for (Stream& s : streams_) s.drops = socket_drops(s.lidar->fd());
  }

  void receive(double duration_s) {
    const int64_t end = monotonic_now_ns() + static_cast<int64_t>(duration_s * 1e9);
    const int64_t realtime_minus_monotonic = realtime_minus_monotonic_ns();
    while (monotonic_now_ns() < end) {
      if (poll(fds_.data(), fds_.size(), 100) <= 0) continue;
      for (size_t i = 0; i < fds_.size(); ++i) {
        if (!(fds_[i].revents & POLLIN)) continue;
        Stream& s = streams_[i / 2];
        const bool lidar = i % 2 == 0;
        receiver_.drain(fds_[i].fd, [&](std::span<const uint8_t> bytes, int64_t received_ns, int64_t arrived_ns) {
          if (lidar) record_packet(bytes, received_ns, arrived_ns, *s.format, realtime_minus_monotonic, s.reception);
        });
      }
    }
    for (Stream& s : streams_) s.drops = socket_drops(s.lidar->fd()) - s.drops;
  }

 private:
  std::vector<Stream>& streams_;
  std::vector<pollfd> fds_;
  BatchReceiver receiver_;
};

// The worst sensor's send lateness p99 from the daemons' "streamer ... stopped after" lines.
double worst_logged_p99_us(const std::vector<std::unique_ptr<Daemon>>& daemons) {
  double worst = 0;
  const std::regex line("streamer[^\n]*stopped after[^\n]*p99 ([0-9]+) us");
  for (const auto& daemon : daemons) {
    const std::string log = daemon->log();
    for (std::sregex_iterator it(log.begin(), log.end(), line), end; it != end; ++it)
      worst = std::max(worst, std::stod((*it)[1].str()));
  }
  return worst;
}

void summarize(const std::vector<Stream>& streams, Row& row, double window_s) {
  double rendered_packets = 0;
  row.fewest_stalls = 100;
  for (const Stream& s : streams) {
    const Reception& r = s.reception;
    const double stalled = r.received ? 100.0 * static_cast<double>(r.blank) / static_cast<double>(r.received) : 100.0;
    row.stalls += r.blank;
    row.fewest_stalls = std::min(row.fewest_stalls, stalled);
    row.most_stalls = std::max(row.most_stalls, stalled);
    const uint64_t missing = lost_packets(r, static_cast<size_t>(s.format->packets_per_frame()));
    row.lost += missing - std::min(missing, s.drops);
    row.rx_drops += s.drops;
    rendered_packets += static_cast<double>(r.received - r.blank);
    row.p99_arrival_us = std::max(row.p99_arrival_us, percentile_us(r.arrival_lateness_ns, 0.99));
  }
  const auto& format = streams.front().format->format();
  row.pixels_per_s = rendered_packets * format.columns_per_packet * format.pixels_per_column / window_s;
}

Row run(const Flags& flags, const std::string& mode, int sensors) {
  Row row;
  row.sensors = sensors;
  row.mode = mode;
  std::vector<std::unique_ptr<Daemon>> daemons;
  try {
    daemons = start_daemons(mode, sensors, flags.serve_args);
    std::vector<Stream> streams(static_cast<size_t>(sensors));
    for_each_sensor(sensors, [&](int i) {
      Stream& s = streams[static_cast<size_t>(i)];
      s.address = address_of(i);
      s.http_port = answering_ports(daemons[mode == "rig" ? 0 : static_cast<size_t>(i)]->log()).at(s.address);
      configure(s);
    });
    std::this_thread::sleep_for(std::chrono::duration<double>(flags.settle_s));
    StreamsReceiver receiver(streams);
    receiver.open_window();
    std::vector<double> cpu_before;
    for (const auto& d : daemons) cpu_before.push_back(cpu_seconds(d->pid()));
    const double machine_before = machine_cpu_seconds();
    const int64_t wall_before = monotonic_now_ns();
    receiver.receive(flags.duration_s);
    const double window_s = static_cast<double>(monotonic_now_ns() - wall_before) * 1e-9;
    const double machine = machine_cpu_seconds() - machine_before;
    for (size_t i = 0; i < daemons.size(); ++i) {
      row.cores += (cpu_seconds(daemons[i]->pid()) - cpu_before[i]) / window_s;
      row.rss_mib += static_cast<double>(rss_kib(daemons[i]->pid())) / 1024.0;
    }
    row.other_cores = std::max(0.0, machine / window_s - row.cores);
    row.load = load_average();
    summarize(streams, row, window_s);
  } catch (const std::exception& e) {
    row.error = e.what();
    row.error = row.error.substr(0, row.error.find('\n'));
  }
  for (auto& daemon : daemons) daemon->stop();
  row.p99_daemon_us = worst_logged_p99_us(daemons);
  return row;
}

// ---- the table ---------------------------------------------------------------------------------

void print_header(double a_prime) {
  std::printf("rig_bench: %s %s %s in scenes/plant.glb (drone lap); (a') = %.1f M rays/s on %u cores\n", kProfile,
              kMode, kUdpProfile, a_prime * 1e-6, std::thread::hardware_concurrency());
  std::printf("%3s %-7s %7s %12s %12s %9s %9s %6s %7s %8s %6s %6s %11s %s\n", "N", "mode", "stalls", "% per sensor",
              "lost (rx)", "p99 log", "p99 recv", "cores", "c/sens", "MiB/sens", "Mpx/s", "/(a')", "other cores",
              "verdict");
}

void print_row(const Row& row, double a_prime) {
  if (!row.error.empty()) {
    std::printf("%3d %-7s failed: %s\n", row.sensors, row.mode.c_str(), row.error.c_str());
    return;
  }
  const double n = row.sensors;
  std::printf(
      "%3d %-7s %7llu %5.1f-%5.1f %5llu (%4llu) %6.0f us %6.0f us %6.2f %7.3f %8.1f %6.2f %6.3f %5.2f (%s) %s\n",
      row.sensors, row.mode.c_str(), static_cast<unsigned long long>(row.stalls), row.fewest_stalls, row.most_stalls,
      static_cast<unsigned long long>(row.lost), static_cast<unsigned long long>(row.rx_drops), row.p99_daemon_us,
      row.p99_arrival_us, row.cores, row.cores / n, row.rss_mib / n, row.pixels_per_s * 1e-6,
      row.pixels_per_s / a_prime, row.other_cores, row.load.c_str(), row.passes() ? "ok" : "FAILS");
  std::fflush(stdout);
}

int run_all(const Flags& flags) {
  const double a_prime = measure_a_prime();
  print_header(a_prime);
  std::map<std::string, int> largest;
  for (const int sensors : flags.counts) {
    if (sensors > flags.max_sensors) continue;
    for (const std::string& mode : flags.modes) {
      const Row row = run(flags, mode, sensors);
      print_row(row, a_prime);
      if (row.passes()) largest[mode] = std::max(largest[mode], sensors);
    }
  }
  std::printf("largest N with 0 stalls, 0 lost, p99 < 1 ms:");
  for (const std::string& mode : flags.modes) std::printf(" %s %d;", mode.c_str(), largest[mode]);
  std::printf(
      "\n(%% per sensor: the least and the most stalled sensor's share of its packets; p99 log: the "
      "daemon's own, whole run; p99 recv: kernel arrival stamp in the window; other cores: the rest of the "
      "machine, this benchmark included, load average in brackets)\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run_all(parse_flags(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rig_bench: %s\n", e.what());
    return 1;
  }
}
