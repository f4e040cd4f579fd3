// Hostile bytes for every decoder. tools/test reruns the suites named Fuzz* under AddressSanitizer
// and UBSan (Debug, asserts on), so a test passes only if nothing reads out of bounds or trips an
// invariant. One suite per decoder: FuzzPacket (lidar), FuzzImuPacket; metadata and pcap suites
// follow the same pattern.
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"
#include "packet_test_util.h"

namespace lidartwin {
namespace {

// Decoded channels can only hold values their fields can carry, whatever the bytes were.
void expect_values_within_fields(const PacketFormat& format, const Scan& scan) {
  for (int f = 0; f < kChannelFieldCount; ++f) {
    const auto field = static_cast<ChannelField>(f);
    if (!format.has_channel(field)) continue;
    const uint32_t max = format.channel_max(field);
    for (uint32_t v : scan.channels[static_cast<size_t>(f)]) ASSERT_LE(v, max) << to_string(field);
  }
}

// A valid packet with random contents, then random bytes flipped: headers, measurement ids and
// footers get arbitrary values while the size stays right, so decoding runs to the end.
TEST(FuzzPacket, MutatedValidPacketsNeverCrash) {
  std::mt19937_64 rng(1234);  // fixed seed: a crash must reproduce
  for (UdpProfileLidar profile : test::kProfiles) {
    for (int height : {16, 128}) {
      const LidarDataFormat f = test::make_format(profile, height, 16, 512);
      const PacketFormat format(f);
      Scan source(f);
      test::fill_random(source, profile, rng);
      std::vector<uint8_t> packet(format.lidar_packet_size());
      Scan scan(f);
      for (int trial = 0; trial < 300; ++trial) {
        format.encode(test::random_header(profile, rng), source, 16 * static_cast<int>(rng() % 32), packet);
        for (int flips = static_cast<int>(rng() % 16); flips >= 0; --flips) {
          packet[rng() % packet.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
        }
        std::string error;
        if (format.decode(packet, scan, &error)) {
          expect_values_within_fields(format, scan);
        } else {
          EXPECT_FALSE(error.empty());
        }
      }
    }
  }
}

// Random bytes of random sizes, including exactly the packet size with a lidar packet_type.
TEST(FuzzPacket, RandomBytesNeverCrash) {
  std::mt19937_64 rng(99);  // fixed seed: a crash must reproduce
  for (UdpProfileLidar profile : test::kProfiles) {
    const LidarDataFormat f = test::make_format(profile, 32, 4, 64);
    const PacketFormat format(f);
    Scan scan(f);
    for (int trial = 0; trial < 500; ++trial) {
      const size_t size = trial % 2 == 0 ? format.lidar_packet_size() : rng() % (2 * format.lidar_packet_size());
      std::vector<uint8_t> bytes(size);
      for (auto& b : bytes) b = static_cast<uint8_t>(rng());
      if (trial % 4 == 0 && size >= 2) {
        bytes[0] = 1;  // packet_type 1 (lidar) in both header layouts, so decoding goes on
        bytes[1] = 0;
      }
      std::string error;
      if (format.decode(bytes, scan, &error)) {
        expect_values_within_fields(format, scan);
      } else {
        EXPECT_FALSE(error.empty());
      }
    }
  }
}

TEST(FuzzPacket, MismatchedScansAreRejected) {
  const LidarDataFormat f = test::make_format(UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual, 64, 16, 1024);
  const PacketFormat format(f);
  std::vector<uint8_t> packet(format.lidar_packet_size());
  Scan empty;
  Scan other_profile(test::make_format(UdpProfileLidar::kRng15Rfl8Nir8, 64, 16, 1024));
  Scan other_cpp(test::make_format(UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual, 64, 8, 1024));
  for (Scan* scan : {&empty, &other_profile, &other_cpp}) {
    std::string error;
    EXPECT_FALSE(format.decode(packet, *scan, &error));
    EXPECT_FALSE(error.empty());
  }
}

TEST(FuzzImuPacket, RandomBytesNeverCrash) {
  std::mt19937_64 rng(5);  // fixed seed: a crash must reproduce
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> bytes(rng() % 100);
    for (auto& b : bytes) b = static_cast<uint8_t>(rng());
    EXPECT_EQ(decode_legacy_imu(bytes).has_value(), bytes.size() == kLegacyImuPacketSize);
  }
  for (int trial = 0; trial < 300; ++trial) {
    const int n = static_cast<int>(rng() % 4);
    std::vector<uint8_t> bytes(trial % 2 == 0 ? nmea_imu_packet_size(n) : rng() % 400);
    for (auto& b : bytes) b = static_cast<uint8_t>(rng());
    if (trial % 4 == 0 && !bytes.empty()) bytes[0] = 2;  // IMU packet_type in both header layouts
    std::string error;
    for (HeaderType type : {HeaderType::kStandard, HeaderType::kFusa}) {
      if (!decode_nmea_imu(bytes, n, type, &error)) {
        EXPECT_FALSE(error.empty());
      }
    }
  }
}

}  // namespace
}  // namespace lidartwin
