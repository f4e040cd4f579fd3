// `lidartwin serve` as a user meets it: bad flags are refused with a message naming the flag,
// --serial-number is the sensor's identity, --record captures exactly what was sent, SIGTERM exits 0.
#include <chrono>
#include <csignal>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <thread>

#include <sys/resource.h>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/pcap/pcap.h"
#include "lidartwin/pose/pose.h"
#include "support/record_capture.h"

namespace lidartwin::e2e::serve_cli_test {
namespace {

// The room's flags, less the one a case replaces (CLI11 refuses a flag given twice).
std::string room_flags(const std::string& replaced) {
  std::string flags;
  const auto args = room_args();
  for (size_t i = 0; i + 1 < args.size(); i += 2) {
    if (args[i] != replaced) flags += " '" + args[i] + "' '" + args[i + 1] + "'";
  }
  return flags;
}

struct BadFlag {
  std::string args;
  std::string named;  // the message must name this
  friend void PrintTo(const BadFlag& flag, std::ostream* out) { *out << flag.args; }
};

class ServeFlags : public ::testing::TestWithParam<BadFlag> {};

TEST_P(ServeFlags, RefusesABadFlagNamingIt) {
  const std::string& args = GetParam().args;
  const auto [code, output] = run_cli("serve --http-port 0" + room_flags(args.substr(0, args.find(' '))) + " " + args);
  EXPECT_NE(code, 0) << output;
  EXPECT_NE(output.find(GetParam().named), std::string::npos) << output;
}

INSTANTIATE_TEST_SUITE_P(
    Flags, ServeFlags,
    ::testing::Values(BadFlag{"--lidar-mode 1000x7", "--lidar-mode"}, BadFlag{"--udp-profile FAST", "--udp-profile"},
                      BadFlag{"--address 300.1.2.3", "--address"}, BadFlag{"--http-port 70000", "--http-port"},
                      BadFlag{"--scene /no/such/scene.glb", "--scene"},
                      BadFlag{"--profile no-such-sensor", "no-such-sensor"},
                      BadFlag{"--trajectory /no/such.tum", "--trajectory"},  // excluded by the --pose of room_args
                      BadFlag{"--threads -3", "--threads"}, BadFlag{"--no-such-flag", "--no-such-flag"},
                      BadFlag{"--serial-number 12ab", "--serial-number"},
                      BadFlag{"--serial-number 1234567890123", "--serial-number"},
                      BadFlag{"--coalesce-us -5", "--coalesce-us"}, BadFlag{"--contention sometimes", "--contention"}));

// A rig's sensors in containers all bind 0.0.0.0, so the address cannot tell their serials apart:
// --serial-number sets the one the metadata reports and every packet carries (4.3).
// Live-pose flags, refused before the daemon binds anything (no --pose: the poses arrive live).
class ServeLiveFlags : public ::testing::TestWithParam<BadFlag> {};

TEST_P(ServeLiveFlags, RefusesABadFlagNamingIt) {
  const auto [code, output] = run_cli("serve --http-port 0 --profile os1-32 --threads 1 --scene '" +
                                      room_scene().string() + "' " + GetParam().args);
  EXPECT_NE(code, 0) << output;
  EXPECT_NE(output.find(GetParam().named), std::string::npos) << output;
}

INSTANTIATE_TEST_SUITE_P(Flags, ServeLiveFlags,
                         ::testing::Values(BadFlag{"--pose-udp 1.2.3:900", "\"1.2.3\" is not an IPv4 address"},
                                           BadFlag{"--pose-udp 127.0.0.1:70000",
                                                   "--pose-udp 127.0.0.1:70000: the port"},
                                           BadFlag{"--live-poses --pose-clock gps", "--pose-clock"},
                                           BadFlag{"--live-poses --pose-timeout pause", "--pose-timeout"},
                                           BadFlag{"--live-poses --pose-extrapolate-ms 10 --cast-ahead-ms 10",
                                                   "--cast-ahead-ms 10: must be less"},
                                           BadFlag{"--live-poses --pose '0 0 1 0 0 0 1'", "leave out --pose"},
                                           BadFlag{"--lock-step --pose-clock monotonic", "--pose-clock"},
                                           BadFlag{"--lock-step --stamp-pose-clock", "--stamp-pose-clock"},
                                           BadFlag{"--live-poses --mount '1 2 3'", "--mount"}));

TEST(ServeIdentity, SerialNumberFlagIsTheSensorsProdSn) {
  UdpSocket lidar;
  auto args = room_args();
  args.insert(args.end(), {"--serial-number", "987654321012"});
  Daemon daemon("127.0.0.1", 0, args);
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  EXPECT_EQ(metadata.sensor_info.prod_sn, "987654321012");
  ScanBatcher batcher(metadata.format);
  expect_complete_scans(receive_scans(lidar, batcher, 1, std::chrono::seconds(10)), metadata, 1);
}

TEST(ServeRecord, CapturesEverySentPacketWithMetadata) {
  const auto dir = scratch_dir() / "record";
  std::filesystem::remove_all(dir);
  UdpSocket lidar;
  UdpSocket imu;
  auto args = room_args();
  args.insert(args.end(), {"--record", dir.string()});
  Daemon daemon("127.0.0.1", 0, args);
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  ScanBatcher batcher(metadata.format);
  expect_complete_scans(receive_scans(lidar, batcher, 2, std::chrono::seconds(10)), metadata, 2);
  ASSERT_EQ(daemon.stop(), 0) << daemon.log();

  const Metadata recorded = load_metadata(dir / "metadata.json");
  EXPECT_EQ(recorded.sensor_info.initialization_id, metadata.sensor_info.initialization_id);
  size_t lidar_packets = 0;
  size_t imu_packets = 0;
  ScanBatcher recorded_frames(metadata.format);
  std::vector<uint64_t> valid_column_times;
  const auto keep_times = [&](const std::optional<BatchedFrame>& frame) {
    if (!frame) return;
    for (size_t m = 0; m < frame->scan.status.size(); ++m) {
      if (frame->scan.status[m] & 1u) valid_column_times.push_back(frame->scan.timestamp_ns[m]);
    }
  };
  for (const auto& datagram : read_pcap(dir / "capture.pcap")) {
    EXPECT_EQ(datagram.src_ip, (std::array<uint8_t, 4>{127, 0, 0, 1}));
    EXPECT_NE(datagram.src_port, lidar.port());  // an ephemeral source port (1 item 8)
    if (datagram.dst_port == lidar.port()) {
      EXPECT_EQ(datagram.payload.size(), batcher.format().lidar_packet_size());
      ++lidar_packets;
      keep_times(recorded_frames.add(datagram.payload));
    } else if (datagram.dst_port == imu.port()) {
      EXPECT_EQ(datagram.payload.size(), 48u);
      ++imu_packets;
    }
  }
  EXPECT_GE(lidar_packets, 3 * batcher.expected_packets());
  EXPECT_GE(imu_packets, 20u);

  // Ground truth as `record` writes it: the pose each sent column was cast from, at its timestamp.
  keep_times(recorded_frames.flush());
  ASSERT_FALSE(valid_column_times.empty());
  // Also there: the columns sent to 7502 under the factory config, before the client's reinit.
  auto column_poses = test::read_poses(dir / "column_poses.tum");
  std::erase_if(column_poses, [&](const auto& row) {
    return row.time_s < static_cast<double>(valid_column_times.front()) * 1e-9 - 1e-9;
  });
  ASSERT_EQ(column_poses.size(), valid_column_times.size());
  const Pose room = parse_pose(kRoomPose);
  for (size_t i = 0; i < column_poses.size(); ++i) {
    ASSERT_NEAR(column_poses[i].time_s, static_cast<double>(valid_column_times[i]) * 1e-9, 1e-9) << i;
    ASSERT_NEAR((column_poses[i].translation - room.translation).norm(), 0.0, 1e-9);
  }
  const auto frame_poses = test::read_poses(dir / "poses.tum");
  EXPECT_GE(frame_poses.size(), 3u);
}

// The disk fills under serve --record (RLIMIT_FSIZE of 2 MB, inherited by the daemon, stands in for
// it; SIGXFSZ ignored so that the write fails as on a full disk; issue 27): the recording stops with
// an error naming the file, the stream and the API go on, and what was recorded stays readable.
TEST(ServeRecord, ADiskThatFillsStopsTheRecordingNotTheStream) {
  const auto dir = scratch_dir() / "record_disk_full";
  std::filesystem::remove_all(dir);
  UdpSocket lidar;
  auto args = room_args();
  args.insert(args.end(), {"--record", dir.string()});
  std::optional<Daemon> daemon;
  {
    rlimit before{};
    getrlimit(RLIMIT_FSIZE, &before);
    rlimit limited = before;
    limited.rlim_cur = 2'000'000;
    const auto previous = std::signal(SIGXFSZ, SIG_IGN);
    setrlimit(RLIMIT_FSIZE, &limited);
    daemon.emplace("127.0.0.1", 0, args);  // forks with the limit
    setrlimit(RLIMIT_FSIZE, &before);
    std::signal(SIGXFSZ, previous);
  }
  SensorHttp http(daemon->address(), daemon->http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "1024x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (daemon->log().find("recording stopped") == std::string::npos && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_NE(daemon->log().find("streamer: --record: " + (dir / "capture.pcap").string() +
                               ": cannot write capture: File too large; recording stopped, streaming goes on"),
            std::string::npos)
      << daemon->log();
  lidar.drain();
  ScanBatcher batcher(metadata.format);
  expect_complete_scans(receive_scans(lidar, batcher, 3, std::chrono::seconds(10)), metadata, 3);
  EXPECT_EQ(http.get_json("sensor/metadata/sensor_info").at("status"), "RUNNING");
  EXPECT_EQ(daemon->stop(), 0) << daemon->log();
  PcapStats stats;
  const std::vector<UdpDatagram> recorded = read_pcap(dir / "capture.pcap", stats);
  EXPECT_GT(recorded.size(), 100u);
  EXPECT_LE(std::filesystem::file_size(dir / "capture.pcap"), 2'000'000u);
  std::filesystem::remove_all(dir);
}

TEST(ServeSignals, SigtermStopsTheDaemonWithExitCodeZero) {
  Daemon daemon("127.0.0.1", 0, room_args());
  const auto started = std::chrono::steady_clock::now();
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(7));
  EXPECT_NE(daemon.log().find("streamer: stopped after"), std::string::npos) << daemon.log();
}

}  // namespace
}  // namespace lidartwin::e2e::serve_cli_test
