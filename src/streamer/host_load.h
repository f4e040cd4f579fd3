#pragma once
// How contended the host's CPUs are, for what costs other processes CPU: the send clock's spin to
// each deadline burns a core for nothing but punctuality, which on an idle host is free and on a
// full one is taken from rendering (a dozen daemons on one host, each spinning its send
// clock at SCHED_FIFO before every packet).
namespace lidartwin::streamer_detail {

// The share of the last 10 s in which some runnable thread waited for a CPU, in percent (Linux's
// pressure stall information, /proc/pressure/cpu "some avg10"); without PSI, the 1-minute load
// average over the number of cores, capped at 100. Reads a file: call it about once a second.
double host_cpu_pressure_percent();

// Whether the host is contended now: one answer for the process (a rig's streamers ask once a
// second each), read at most once a second, with hysteresis (HostContention); a change is logged
// once, naming the pressure.
bool host_contended();

// Hysteresis over host_cpu_pressure_percent(), so that a host near the threshold does not flip the
// send clock between spinning and sleeping every second.
class HostContention {
 public:
  // Returns whether the host is contended after this reading.
  bool update(double pressure_percent) {
    if (pressure_percent >= kContendedPercent) contended_ = true;
    if (pressure_percent <= kFreePercent) contended_ = false;
    return contended_;
  }
  bool contended() const { return contended_; }

  // One daemon streaming on an idle 2-core VM reads 1-8 %; a dozen daemons, or a compiler on
  // every core beside one, 40-98 %.
  static constexpr double kContendedPercent = 20.0;
  static constexpr double kFreePercent = 10.0;

 private:
  bool contended_ = false;
};

}  // namespace lidartwin::streamer_detail
