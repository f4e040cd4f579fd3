// Coalesced sends (issue 26): on a contended host whose casting fell behind, a daemon's send clock
// wakes once for the packets due within --coalesce-us of each other and holds the earlier ones
// back, and sends the IMU samples due by then with them (a wake-up costs ~100 us of CPU on a VM:
// a dozen daemons' per-packet wake-ups took the CPU their casting needed). `--contention always`
// makes the daemon treat the host as contended from the start, as a user with a CPU quota that
// the host's pressure does not show would.
//
// What a client sees then: every packet, in order, none before its time (its last column's
// timestamp, on the host's CLOCK_MONOTONIC in TIME_FROM_INTERNAL_OSC) and none held back more than
// the window; at 1024x10 (a packet every 1.56 ms) the packets come in pairs; IMU samples all come,
// none early and none later than the window. With `--contention never` they come one by one.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <ctime>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin::e2e::coalesced_sends_test {
namespace {

constexpr int64_t kWindowNs = 2'000'000;        // --coalesce-us 2000, the default
constexpr int64_t kPacketPeriodNs = 1'562'500;  // 1024x10, 16 columns a packet
constexpr int64_t kImuPeriodNs = 10'000'000;
// A pair's second packet leaves right after the first: well under a packet period apart.
constexpr int64_t kPairGapNs = 400'000;
// Arrival stamps are on CLOCK_REALTIME, converted with two clock reads back to back.
constexpr int64_t kClockToleranceNs = 20'000;

int64_t realtime_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct Arrival {
  int64_t timestamp_ns = 0;  // the packet's: its last column's, or the IMU sample's
  int64_t arrived_ns = 0;    // when the kernel queued it, on CLOCK_MONOTONIC
  uint32_t frame_id = 0;
  int first_column = 0;
};

struct Streams {
  std::vector<Arrival> lidar;
  std::vector<Arrival> imu;
  size_t invalid_columns = 0;
  double coalesce_window_us = -1;  // as the daemon's telemetry reports it at the end
};

Streams receive(UdpSocket& lidar, UdpSocket& imu, const Metadata& metadata, std::chrono::milliseconds duration) {
  Streams streams;
  const PacketFormat format(metadata.format);
  const auto end = std::chrono::steady_clock::now() + duration;
  while (std::chrono::steady_clock::now() < end) {
    if (auto d = lidar.receive(std::chrono::milliseconds(1))) {
      const int64_t to_monotonic = monotonic_now_ns() - realtime_now_ns();  // read at once: no slewing between
      Scan scan(metadata.format);
      if (const auto decoded = format.decode(d->bytes, scan, nullptr)) {
        const int columns = metadata.format.columns_per_packet;
        const int last = decoded->first_measurement_id + columns - 1;
        for (int c = decoded->first_measurement_id; c <= last; ++c) streams.invalid_columns += !scan.column_valid(c);
        streams.lidar.push_back({static_cast<int64_t>(scan.timestamp_ns[static_cast<size_t>(last)]),
                                 d->arrived_ns + to_monotonic, decoded->header.frame_id,
                                 decoded->first_measurement_id});
      }
    }
    while (auto d = imu.receive(std::chrono::milliseconds(0))) {
      const int64_t to_monotonic = monotonic_now_ns() - realtime_now_ns();
      if (const auto sample = decode_legacy_imu(d->bytes))
        streams.imu.push_back({static_cast<int64_t>(sample->sys_ts_ns), d->arrived_ns + to_monotonic, 0, 0});
    }
  }
  return streams;
}

Streams stream_with(const std::string& contention) {
  auto args = room_args("os1-64");
  args.insert(args.end(), {"--contention", contention});
  Daemon daemon("127.0.0.1", 0, args);
  SensorHttp http(daemon.address(), daemon.http_port());
  UdpSocket lidar, imu;
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  request.lidar_mode = "1024x10";
  request.timestamp_mode = "TIME_FROM_INTERNAL_OSC";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  // The stream starts a quarter second after the reinit; what came before was the old config's.
  receive(lidar, imu, metadata, std::chrono::milliseconds(400));
  Streams streams = receive(lidar, imu, metadata, std::chrono::milliseconds(1500));
  streams.coalesce_window_us = http.get_json("sensor/telemetry").at("lidartwin").at("coalesce_window_us").get<double>();
  return streams;
}

// Share of consecutive lidar packets that arrived within kPairGapNs of the one before.
double paired_share(const std::vector<Arrival>& lidar) {
  size_t pairs = 0;
  for (size_t i = 1; i < lidar.size(); ++i) pairs += lidar[i].arrived_ns - lidar[i - 1].arrived_ns < kPairGapNs;
  return lidar.size() > 1 ? static_cast<double>(pairs) / static_cast<double>(lidar.size() - 1) : 0.0;
}

TEST(CoalescedSends, PacketsComeInPairsNoneBeforeItsTimeNoneLostAndImuRidesAlong) {
  const Streams streams = stream_with("always");
  ASSERT_GT(streams.lidar.size(), 600u);  // 640 a second
  EXPECT_EQ(streams.invalid_columns, 0u) << "the room casts in time: no column goes out unrendered";

  // Every packet, in order: each follows the one before it (64 packets a frame, frame_id + 1 after
  // the last).
  for (size_t i = 1; i < streams.lidar.size(); ++i) {
    const Arrival& a = streams.lidar[i - 1];
    const Arrival& b = streams.lidar[i];
    const bool next_in_frame = b.frame_id == a.frame_id && b.first_column == a.first_column + 16;
    const bool next_frame =
        b.frame_id == static_cast<uint16_t>(a.frame_id + 1) && a.first_column == 1008 && b.first_column == 0;
    ASSERT_TRUE(next_in_frame || next_frame)
        << "packet " << i << ": frame " << b.frame_id << " column " << b.first_column << " after frame " << a.frame_id
        << " column " << a.first_column;
  }

  // None before its time. The sensor clock's offset from this host's CLOCK_MONOTONIC is zero in
  // INTERNAL_OSC; a packet arriving before its timestamp would have been sent early.
  int64_t earliest_ns = INT64_MAX;
  for (const Arrival& a : streams.lidar) earliest_ns = std::min(earliest_ns, a.arrived_ns - a.timestamp_ns);
  EXPECT_GE(earliest_ns, -kClockToleranceNs)
      << "a packet arrived " << -earliest_ns << " ns before its last column's time";
  // Held back: about half the packets by a packet period (the earlier of each pair). A host that
  // delays the daemon makes some later still, so the test asks for the held ones, not a maximum.
  size_t held = 0;
  for (const Arrival& a : streams.lidar) held += a.arrived_ns - a.timestamp_ns > kPacketPeriodNs / 2;
  EXPECT_GT(static_cast<double>(held) / static_cast<double>(streams.lidar.size()), 0.35);
  EXPECT_GT(paired_share(streams.lidar), 0.35) << "one wake-up for every two packets";
  EXPECT_EQ(streams.coalesce_window_us, 2000.0) << "casting keeps up: the window stays at --coalesce-us";

  // IMU: every sample in order, none early, and most within the window after their time (they go
  // with the lidar wake-up after them).
  ASSERT_GT(streams.imu.size(), 120u);  // 100 a second
  size_t within = 0;
  for (size_t i = 0; i < streams.imu.size(); ++i) {
    const Arrival& a = streams.imu[i];
    if (i > 0) {
      EXPECT_EQ(a.timestamp_ns - streams.imu[i - 1].timestamp_ns, kImuPeriodNs) << "IMU sample " << i;
    }
    EXPECT_GE(a.arrived_ns, a.timestamp_ns - kClockToleranceNs) << "IMU sample " << i << " arrived before its time";
    within += a.arrived_ns - a.timestamp_ns <= kWindowNs + 500'000;
  }
  EXPECT_GT(static_cast<double>(within) / static_cast<double>(streams.imu.size()), 0.8);
}

TEST(CoalescedSends, NeverMeansOneWakeUpAPacket) {
  const Streams streams = stream_with("never");
  ASSERT_GT(streams.lidar.size(), 600u);
  // On an idle host none come in pairs; a busy host that delays a wake-up past the next deadline
  // makes a few.
  EXPECT_LT(paired_share(streams.lidar), 0.2);
  EXPECT_EQ(streams.coalesce_window_us, 0.0);
}

}  // namespace
}  // namespace lidartwin::e2e::coalesced_sends_test
