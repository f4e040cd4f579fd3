// Read-only status endpoints no SDK client needs but tools and HIL tests read (protocol doc 2.3,
// 2.5), and the zone monitor, which FW 3.1 does not have.
#include <chrono>
#include <cstdio>

#include "http_api/api_util.h"
#include "http_api/routes.h"

namespace lidartwin {
namespace {

using nlohmann::json;

double seconds_since_epoch() {
  using namespace std::chrono;
  return duration<double>(system_clock::now().time_since_epoch()).count();
}

// Every time these endpoints report is the sensor's time base (sensor/time_base.h): the clocks the
// packets are stamped on, read at one steady-clock instant per request.
double seconds(int64_t ns) { return static_cast<double>(ns) * 1e-9; }

// The replay tool's shape with numbers, plus what the streamer reports (StreamStats).
ApiResponse get_telemetry(Sensor& sensor, const ApiRequest&) {
  const auto stats = sensor.stream_stats();
  const bool phase_lock = sensor.active_config().value("phase_lock_enable", false);
  // The sensor's time in its timestamp_mode, as the packets it sends now carry.
  const int64_t now_ns = sensor.time().now_ns(sensor.timestamp_mode());
  return json_response({
      {"input_current_ma", 693},
      {"input_voltage_mv", 23879},
      {"internal_temperature_deg_c", 48},
      {"phase_lock_status", phase_lock ? "LOCKED" : "DISABLED"},
      {"timestamp_ns", now_ns},
      {"lidartwin",
       {{"lidar_packets_sent", stats.lidar_packets_sent},
        {"imu_packets_sent", stats.imu_packets_sent},
        {"frames_sent", stats.frames_sent},
        {"late_packets", stats.late_packets},
        {"render_stalls", stats.render_stalls},
        {"skipped_packets", stats.skipped_packets},
        {"send_lateness_p50_us", stats.lateness_p50_us},
        {"send_lateness_p99_us", stats.lateness_p99_us},
        {"max_lateness_us", stats.max_lateness_us},
        {"render_load", stats.render_load},
        {"coalesce_window_us", stats.coalesce_window_us}}},
  });
}

// The sensor's Linux clocks: its CLOCK_MONOTONIC is the internal oscillator's time (since power-on).
ApiResponse get_time_system(Sensor& sensor, const ApiRequest&) {
  return json_response(
      {{"monotonic", seconds(sensor.time().now_ns(TimestampMode::kInternalOsc))}, {"realtime", seconds_since_epoch()}});
}

// A reduced FW 2.x/3.x shape: "time" is the active timestamp_mode's clock, "time_options" what
// each clock reads at the same instant (seconds). When the packets carry another clock (lock-step's
// simulation time, --stamp-pose-clock's poses' clock), every reading is that clock's: what a client
// compares with the packets' timestamps.
ApiResponse get_time_sensor(Sensor& sensor, const ApiRequest&) {
  const auto config = sensor.active_config();
  const TimeBase& time = sensor.time();
  const int64_t steady_ns = TimeBase::steady_now_ns();
  const std::optional<int64_t> packets_ns = sensor.packets_clock_ns();
  const auto at = [&](TimestampMode mode) { return seconds(packets_ns ? *packets_ns : time.time_ns(mode, steady_ns)); };
  return json_response({
      {"timestamp",
       {{"mode", config.value("timestamp_mode", "TIME_FROM_INTERNAL_OSC")},
        {"time", at(sensor.timestamp_mode())},
        {"time_options",
         {{"internal_osc", at(TimestampMode::kInternalOsc)},
          {"sync_pulse_in", at(TimestampMode::kSyncPulseIn)},
          {"ptp_1588", at(TimestampMode::kPtp1588)}}}}},
      {"sync_pulse_in",
       {{"locked", 0},
        {"polarity", config.value("sync_pulse_in_polarity", "ACTIVE_HIGH")},
        {"diagnostics", {{"count", 0}, {"count_unfiltered", 0}, {"last_period_nsec", 0}}}}},
      {"multipurpose_io", {{"mode", config.value("multipurpose_io_mode", "OFF")}}},
  });
}

ApiResponse get_time_ptp(Sensor&, const ApiRequest&) {
  return json_response({{"profile", "default"},
                        {"port_data_set", {{"port_state", "LISTENING"}}},
                        {"current_data_set", {{"offset_from_master", 0}, {"steps_removed", 0}}},
                        {"parent_data_set", json::object()},
                        {"time_properties_data_set", json::object()}});
}

// Keys read by Ouster's HIL tests (protocol doc 2.5, inferred shape). Alerts come only from an
// injected ERROR (docs/fault-injection.md).
ApiResponse get_alerts(Sensor& sensor, const ApiRequest&) { return json_response(sensor.alerts()); }

ApiResponse get_network(Sensor& sensor, const ApiRequest& request) {
  const auto& sn = sensor.identity().prod_sn;
  const unsigned tail = static_cast<unsigned>(std::stoull(sn) & 0xFFFFu);
  char ethaddr[18];
  std::snprintf(ethaddr, sizeof ethaddr, "bc:0f:a7:00:%02x:%02x", tail >> 8, tail & 0xFFu);
  return json_response({
      {"carrier", true},
      {"duplex", "full"},
      {"ethaddr", ethaddr},
      {"hostname", "os-" + sn},
      {"ipv4", {{"addr", request.local_ip + "/8"}, {"link_local", "169.254.0.1/16"}, {"override", nullptr}}},
      {"ipv6", {{"link_local", "fe80::be0f:a7ff:fe00:1/64"}}},
      {"speed", 1000},
      {"speed_override", nullptr},
  });
}

// FW 3.1 has no zone monitor; the SDK only asks for it from FW 3.2 on and accepts a 404
// (protocol doc 2.3, 2.4 (d) 5).
ApiResponse zone_monitor(Sensor&, const ApiRequest&) {
  throw HttpError(404, "zone monitoring is not available: this sensor runs FW 3.1 (it needs 3.2)");
}

}  // namespace

std::vector<Route> misc_routes() {
  return {
      {"GET", "sensor/telemetry", false, get_telemetry}, {"GET", "time/system", false, get_time_system},
      {"GET", "time/sensor", false, get_time_sensor},    {"GET", "time/ptp", false, get_time_ptp},
      {"GET", "sensor/alerts", false, get_alerts},       {"GET", "system/network", false, get_network},
      {"*", "zone_monitor", false, zone_monitor},        {"*", "zone_monitor", true, zone_monitor},
  };
}

}  // namespace lidartwin
