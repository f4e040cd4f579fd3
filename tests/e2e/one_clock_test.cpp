// A sensor reports one clock everywhere (protocol doc 6.3; sensor/time_base.h): the timestamps of
// its lidar and IMU packets, GET time/sensor and telemetry's timestamp_ns agree, in
// TIME_FROM_INTERNAL_OSC (the host's CLOCK_MONOTONIC) and TIME_FROM_PTP_1588 (TAI).
//
// The packets are the reference clock. The daemon sends each packet when its timestamp comes due
// (a lidar packet's last column, an IMU sample), so (timestamp - when the kernel queued it, on
// this host's CLOCK_MONOTONIC) is the sensor clock's offset from the host's, less the packet's
// delay; the largest over many packets comes within one packet period of it (a packet held up
// longer than that is late). A time read over HTTP between t0 and t1 (CLOCK_MONOTONIC) must then
// lie in [t0, t1] + offset, within that one period. (The kernel's arrival time, not the time this
// test reads the packet: a test starved by a busy host reads tens of milliseconds behind.)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <limits>
#include <string>

#include "e2e/support/room.h"

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin::e2e::one_clock_test {
namespace {

constexpr int64_t kLidarPeriodNs = 3'125'000;  // 512x10, 16 columns per packet: 16 / 5120 s
constexpr int64_t kImuPeriodNs = 10'000'000;   // 100 Hz (5.1)

// The sensor clock's offset from this host's CLOCK_MONOTONIC, as the least delayed packet shows it.
struct PacketClock {
  int64_t offset_ns = std::numeric_limits<int64_t>::min();
  size_t packets = 0;
  void add(uint64_t timestamp_ns, int64_t received_ns) {
    offset_ns = std::max(offset_ns, static_cast<int64_t>(timestamp_ns) - received_ns);
    ++packets;
  }
};

struct Clocks {
  PacketClock lidar;
  PacketClock imu;
};

int64_t realtime_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// CLOCK_MONOTONIC less CLOCK_REALTIME, read back to back (within a microsecond).
int64_t monotonic_minus_realtime_ns() {
  const int64_t realtime = realtime_now_ns();
  return monotonic_now_ns() - realtime;
}

// Receives lidar and IMU packets for `duration`.
Clocks receive(UdpSocket& lidar, UdpSocket& imu, const Metadata& metadata, std::chrono::milliseconds duration) {
  Clocks clocks;
  const PacketFormat format(metadata.format);
  Scan scan(metadata.format);
  const int64_t to_monotonic = monotonic_minus_realtime_ns();
  const auto end = std::chrono::steady_clock::now() + duration;
  while (std::chrono::steady_clock::now() < end) {
    if (auto d = lidar.receive(std::chrono::milliseconds(1))) {
      if (const auto decoded = format.decode(d->bytes, scan, nullptr)) {
        const int last = decoded->first_measurement_id + metadata.format.columns_per_packet - 1;
        clocks.lidar.add(scan.timestamp_ns[static_cast<size_t>(last)], d->arrived_ns + to_monotonic);
      }
    }
    if (auto d = imu.receive(std::chrono::milliseconds(0))) {
      if (const auto sample = decode_legacy_imu(d->bytes))
        clocks.imu.add(sample->sys_ts_ns, d->arrived_ns + to_monotonic);
    }
  }
  return clocks;
}

// A time the daemon reported (ns) between t0 and t1 on this host's CLOCK_MONOTONIC.
struct Reading {
  int64_t t0 = 0;
  int64_t t1 = 0;
  int64_t value_ns = 0;
};

template <class Read>
Reading read_between(Read read) {
  Reading r;
  r.t0 = monotonic_now_ns();
  r.value_ns = read();
  r.t1 = monotonic_now_ns();
  return r;
}

// The reading lies where the packets' clock says, within the request's round trip and one period.
void expect_on_packet_clock(const Reading& r, const PacketClock& clock, int64_t period_ns, const std::string& what) {
  ASSERT_GT(clock.packets, 10u) << what;
  const int64_t low = r.t0 + clock.offset_ns;
  const int64_t high = r.t1 + clock.offset_ns + period_ns;
  EXPECT_GE(r.value_ns, low) << what << " reads " << (low - r.value_ns) * 1e-9 << " s before the packets' clock";
  EXPECT_LE(r.value_ns, high) << what << " reads " << (r.value_ns - high) * 1e-9 << " s after the packets' clock";
}

int64_t ns(double seconds) { return std::llround(seconds * 1e9); }

class OneClock : public ::testing::Test {
 protected:
  // Configures the mode as a client would, then listens for half a second.
  void configure(const std::string& mode) {
    ConfigRequest request;
    request.lidar_port = lidar_.port();
    request.imu_port = imu_.port();
    request.lidar_mode = "512x10";
    request.timestamp_mode = mode;
    metadata_ = parse(sdk016_init_client(http_, request));
    ASSERT_EQ(metadata_.config_params.value("timestamp_mode", ""), mode);
    // The new stream starts a quarter second after the reinit; what came before was the old one's.
    receive(lidar_, imu_, metadata_, std::chrono::milliseconds(400));
    clocks_ = receive(lidar_, imu_, metadata_, std::chrono::milliseconds(500));
  }

  Reading time_sensor(const std::string& key) {
    return read_between([&] {
      const json answer = http_.get_json("time/sensor").at("timestamp");
      return ns(key == "time" ? answer.at("time").get<double>() : answer.at("time_options").at(key).get<double>());
    });
  }
  Reading telemetry() {
    return read_between([&] { return http_.get_json("sensor/telemetry").at("timestamp_ns").get<int64_t>(); });
  }

  UdpSocket lidar_;
  UdpSocket imu_;
  Daemon daemon_{"127.0.0.1", 0, room_args()};
  SensorHttp http_{daemon_.address(), daemon_.http_port()};
  Metadata metadata_;
  Clocks clocks_;
};

TEST_F(OneClock, PacketsTimeEndpointsAndTelemetryAgreeInInternalOscAndPtp) {
  configure("TIME_FROM_INTERNAL_OSC");
  // The lidar and IMU streams keep one clock.
  EXPECT_LE(std::abs(clocks_.lidar.offset_ns - clocks_.imu.offset_ns), kImuPeriodNs);
  expect_on_packet_clock(time_sensor("time"), clocks_.lidar, kLidarPeriodNs, "INTERNAL_OSC: time/sensor time");
  expect_on_packet_clock(time_sensor("internal_osc"), clocks_.lidar, kLidarPeriodNs, "time/sensor internal_osc");
  expect_on_packet_clock(time_sensor("time"), clocks_.imu, kImuPeriodNs, "INTERNAL_OSC: time/sensor vs IMU");
  expect_on_packet_clock(telemetry(), clocks_.lidar, kLidarPeriodNs, "INTERNAL_OSC: telemetry timestamp_ns");
  expect_on_packet_clock(read_between([&] { return ns(http_.get_json("time/system").at("monotonic").get<double>()); }),
                         clocks_.lidar, kLidarPeriodNs, "time/system monotonic");
  const PacketClock osc = clocks_.lidar;

  configure("TIME_FROM_PTP_1588");
  EXPECT_LE(std::abs(clocks_.lidar.offset_ns - clocks_.imu.offset_ns), kImuPeriodNs);
  expect_on_packet_clock(time_sensor("time"), clocks_.lidar, kLidarPeriodNs, "PTP: time/sensor time");
  expect_on_packet_clock(time_sensor("ptp_1588"), clocks_.lidar, kLidarPeriodNs, "time/sensor ptp_1588");
  expect_on_packet_clock(time_sensor("time"), clocks_.imu, kImuPeriodNs, "PTP: time/sensor vs IMU");
  expect_on_packet_clock(telemetry(), clocks_.lidar, kLidarPeriodNs, "PTP: telemetry timestamp_ns");
  // The other clocks go on being reported, each the one it was.
  expect_on_packet_clock(time_sensor("internal_osc"), osc, kLidarPeriodNs, "PTP: time/sensor internal_osc");
  // PTP time is TAI: this host's wall clock plus 37 s.
  // (Within two packet periods: the offset's one, and NTP slewing the wall clock by up to 0.5 ms
  // per second since the daemon read it.)
  const int64_t tai_minus_monotonic = 37'000'000'000 - monotonic_minus_realtime_ns();
  EXPECT_NEAR(static_cast<double>(clocks_.lidar.offset_ns - tai_minus_monotonic), 0.0, 2.0 * kLidarPeriodNs);
}

}  // namespace
}  // namespace lidartwin::e2e::one_clock_test
