#include "streamer/host_load.h"

#include <algorithm>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>

#include <spdlog/spdlog.h>

#include "streamer/session_timing.h"

namespace lidartwin::streamer_detail {

double host_cpu_pressure_percent() {
  std::ifstream pressure("/proc/pressure/cpu");
  for (std::string word; pressure >> word;) {
    if (word.rfind("avg10=", 0) == 0) return std::stod(word.substr(6));  // the first: "some"
  }
  std::ifstream loadavg("/proc/loadavg");
  double load = 0.0;
  if (!(loadavg >> load)) return 0.0;
  const double cores = std::max(1u, std::thread::hardware_concurrency());
  return std::min(100.0, 100.0 * load / cores);
}

bool host_contended() {
  static std::mutex mutex;
  static HostContention state;
  static int64_t next_read_ns = 0;
  std::lock_guard lock(mutex);
  const int64_t now = steady_now_ns();
  if (now < next_read_ns) return state.contended();
  next_read_ns = now + 1'000'000'000;
  const bool was = state.contended();
  const double pressure = host_cpu_pressure_percent();
  if (state.update(pressure) == was) return was;
  if (!was) {
    spdlog::info(
        "streamer: the host's CPUs are contended (pressure {:.0f} %): send clocks sleep to each packet's deadline "
        "instead of spinning to it",
        pressure);
  } else {
    spdlog::info(
        "streamer: the host's CPUs are free again (pressure {:.0f} %): send clocks spin to each packet's "
        "deadline, one wake-up a packet",
        pressure);
  }
  return !was;
}

}  // namespace lidartwin::streamer_detail
