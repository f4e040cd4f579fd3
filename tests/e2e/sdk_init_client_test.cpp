// SDK-0.16 init_client (protocol doc 2.4 (c)) against the real daemon: scans assemble completely,
// exactly as the SDK's ScanBatcher assembles them, for several lidar modes and UDP profiles, and
// IMU packets arrive at 100 Hz.
#include <cmath>
#include <string>
#include <tuple>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/packet/imu_packet.h"

namespace lidartwin::e2e::sdk_init_client_test {
namespace {

using Case = std::tuple<std::string, std::string>;  // lidar_mode, udp_profile_lidar

class InitClient : public ::testing::TestWithParam<Case> {};

TEST_P(InitClient, StreamsCompleteScansOfTheRequestedFormat) {
  const auto& [mode, profile] = GetParam();
  UdpSocket lidar;
  UdpSocket imu;
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_mode = mode;
  request.udp_profile_lidar = profile;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  const Metadata metadata = parse(sdk016_init_client(http, request));
  EXPECT_EQ(to_string(LidarMode{metadata.format.columns_per_frame, metadata.format.fps}), mode);
  EXPECT_EQ(to_string(metadata.format.udp_profile_lidar), profile);

  ScanBatcher batcher(metadata.format);
  const auto scans = receive_scans(lidar, batcher, 4, std::chrono::seconds(20), "127.0.0.1");
  expect_complete_scans(scans, metadata, 4);
  EXPECT_EQ(batcher.counts().wrong_size, 0u);
  EXPECT_EQ(batcher.counts().undecodable, 0u);
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

INSTANTIATE_TEST_SUITE_P(ModesAndProfiles, InitClient,
                         ::testing::Values(Case{"512x10", "RNG19_RFL8_SIG16_NIR16"}, Case{"1024x10", "RNG15_RFL8_NIR8"},
                                           Case{"512x20", "LEGACY"}, Case{"1024x20", "RNG19_RFL8_SIG16_NIR16_DUAL"}),
                         [](const ::testing::TestParamInfo<Case>& test) {
                           return std::get<0>(test.param) + "_" + std::get<1>(test.param);
                         });

// LEGACY IMU (5.1): 48 bytes at 100 Hz, stamped in the lidar's clock, reading +1 g up at rest.
TEST(InitClientImu, ImuPacketsArriveAtOneHundredHertz) {
  UdpSocket lidar;
  UdpSocket imu;
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  sdk016_init_client(http, request);

  std::vector<ImuSample> samples;
  while (samples.size() < 50) {
    const auto datagram = imu.receive(std::chrono::seconds(2));
    ASSERT_TRUE(datagram) << "no IMU packet within 2 s";
    ASSERT_EQ(datagram->bytes.size(), kLegacyImuPacketSize);
    EXPECT_EQ(datagram->source_ip, "127.0.0.1");
    const auto sample = decode_legacy_imu(datagram->bytes);
    ASSERT_TRUE(sample);
    samples.push_back(*sample);
  }
  for (size_t i = 1; i < samples.size(); ++i) {
    EXPECT_EQ(samples[i].sys_ts_ns - samples[i - 1].sys_ts_ns, 10'000'000u) << "IMU packet " << i;
  }
  // At rest: +1 g up and no rotation, within the profile's IMU noise (2.3 mg and 0.15 deg/s per
  // axis, and a 0.1 deg/s g-sensitivity offset on z; tests/cli_record_geometry_test.cpp checks
  // the statistics).
  for (const auto& s : samples) {
    EXPECT_NEAR(s.accel_g[2], 1.0f, 0.015f);
    EXPECT_NEAR(std::hypot(s.gyro_deg_s[0], s.gyro_deg_s[1], s.gyro_deg_s[2]), 0.0, 1.2);
    EXPECT_GT(s.accel_ts_ns, 0u);
  }
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

}  // namespace
}  // namespace lidartwin::e2e::sdk_init_client_test
