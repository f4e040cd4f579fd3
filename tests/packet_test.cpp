// Packet formats checked against independent answers: the protocol doc's tables (typed in here
// again, not taken from the code), real header bytes from the sample captures, a bitwise CRC, and
// randomized encode -> decode round trips.
#include <algorithm>
#include <cstring>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/error.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"
#include "packet_test_util.h"

namespace lidartwin {
namespace {

using test::ExpectedField;
using test::kExpectedFields;
using test::kProfiles;
using test::make_format;

// Protocol doc 4.1, packet bytes with columns_per_packet = 16, for H = 16, 32, 64, 128.
struct ExpectedSizes {
  UdpProfileLidar profile;
  std::array<size_t, 4> bytes;
};
constexpr std::array<ExpectedSizes, 6> kDocSizes{{
    {UdpProfileLidar::kLegacy, {3392, 6464, 12608, 24896}},
    {UdpProfileLidar::kRng19Rfl8Sig16Nir16, {3328, 6400, 12544, 24832}},
    {UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual, {4352, 8448, 16640, 33024}},
    {UdpProfileLidar::kRng15Rfl8Nir8, {1280, 2304, 4352, 8448}},
    {UdpProfileLidar::kRng15Rfl8Nir8Dual, {2304, 4352, 8448, 16640}},
    {UdpProfileLidar::kFusaRng15Rfl8Nir8Dual, {2304, 4352, 8448, 16640}},
}};

TEST(Packet, SizesMatchProtocolTable) {
  const std::array<int, 4> heights{16, 32, 64, 128};
  for (const auto& expected : kDocSizes) {
    for (size_t i = 0; i < heights.size(); ++i) {
      const PacketFormat format(make_format(expected.profile, heights[i], 16));
      EXPECT_EQ(format.lidar_packet_size(), expected.bytes[i]) << to_string(expected.profile) << " H=" << heights[i];
    }
  }
}

TEST(Packet, ChannelsAndWidthsMatchIndependentTable) {
  for (UdpProfileLidar profile : kProfiles) {
    const PacketFormat format(make_format(profile, 16, 16));
    for (int f = 0; f < kChannelFieldCount; ++f) {
      const auto field = static_cast<ChannelField>(f);
      const ExpectedField* e = test::expected_field(profile, field);
      ASSERT_EQ(format.has_channel(field), e != nullptr) << to_string(profile) << " " << to_string(field);
      if (e == nullptr) continue;
      EXPECT_EQ(format.channel_max(field), ((uint64_t{1} << e->bit_width) - 1) << e->upshift)
          << to_string(profile) << " " << to_string(field);
      EXPECT_EQ(format.channel_step(field), 1u << e->upshift) << to_string(profile) << " " << to_string(field);
    }
  }
}

// One pixel with one field at its maximum: exactly that field's bits of the pixel are set.
TEST(Packet, FieldBitPositionsMatchIndependentTable) {
  for (const ExpectedField& e : kExpectedFields) {
    const LidarDataFormat data_format = make_format(e.profile, 1, 1, 4);
    const PacketFormat format(data_format);
    Scan scan(data_format);
    scan.at(e.field, 0, 0) = format.channel_max(e.field);
    std::vector<uint8_t> packet(format.lidar_packet_size());
    format.encode(PacketHeader{}, scan, 0, packet, FooterKind::kZero);
    const size_t pixel_start = test::legacy(e.profile) ? 16 : 32 + 12;
    std::set<int> set_bits;
    for (size_t byte = pixel_start; byte < packet.size() - (test::legacy(e.profile) ? 4 : 32); ++byte) {
      for (int bit = 0; bit < 8; ++bit) {
        if ((packet[byte] >> bit) & 1) set_bits.insert(static_cast<int>(byte - pixel_start) * 8 + bit);
      }
    }
    std::set<int> expected;
    for (int b = e.bit_offset; b < e.bit_offset + e.bit_width; ++b) expected.insert(b);
    EXPECT_EQ(set_bits, expected) << to_string(e.profile) << " " << to_string(e.field);
  }
}

TEST(Packet, ScanAllocatesTheProfilesChannels) {
  const LidarDataFormat f = make_format(UdpProfileLidar::kRng15Rfl8Nir8, 32, 16, 1024);
  const Scan scan(f);
  EXPECT_EQ(scan.width, 1024);
  EXPECT_EQ(scan.height, 32);
  EXPECT_EQ(scan.timestamp_ns.size(), 1024u);
  EXPECT_EQ(scan.status.size(), 1024u);
  EXPECT_EQ(scan.packet_received.size(), 64u);
  EXPECT_EQ(scan.channels[static_cast<size_t>(ChannelField::kRange)].size(), 1024u * 32u);
  EXPECT_TRUE(scan.has(ChannelField::kNearIr));
  EXPECT_FALSE(scan.has(ChannelField::kSignal));
  EXPECT_FALSE(scan.has(ChannelField::kRange2));
}

std::string construction_error(const LidarDataFormat& f) {
  try {
    PacketFormat format(f);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Packet, InvalidFormatsThrowNamingTheValue) {
  auto f = make_format(UdpProfileLidar::kLegacy, 64, 16);
  f.pixels_per_column = 0;
  EXPECT_NE(construction_error(f).find("pixels_per_column: must be 1..128, got 0"), std::string::npos);
  f.pixels_per_column = 129;
  EXPECT_NE(construction_error(f).find("got 129"), std::string::npos);
  f = make_format(UdpProfileLidar::kLegacy, 64, 16);
  f.columns_per_packet = 65;
  EXPECT_NE(construction_error(f).find("columns_per_packet: must be 1..64, got 65"), std::string::npos);
  f.columns_per_packet = 3;  // 512 % 3 != 0
  EXPECT_NE(construction_error(f).find("columns_per_frame: must be a multiple of columns_per_packet 3, got 512"),
            std::string::npos);
  f = make_format(UdpProfileLidar::kLegacy, 64, 16);
  f.column_window = {0, 512};
  EXPECT_NE(construction_error(f).find("column_window[1]: must be 0..511, got 512"), std::string::npos);
  // 32 + 64 * (12 + 128 * 16) + 32 = 131904 bytes.
  f = make_format(UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual, 128, 64);
  EXPECT_NE(construction_error(f).find("131904 bytes"), std::string::npos) << construction_error(f);
  f = make_format(UdpProfileLidar::kLegacy, 64, 16);
  f.udp_profile_imu = UdpProfileImu::kAccel32Gyro32Nmea;
  f.imu_measurements_per_packet = 8;
  EXPECT_EQ(PacketFormat(f).imu_packet_size(), 452u);  // protocol doc 5.2, imu_zm_no_lidar.pcap
  f.imu_measurements_per_packet = 0;
  EXPECT_NE(construction_error(f).find("imu_measurements_per_packet"), std::string::npos);
}

TEST(Packet, LegacyColumnsCarryFrameIdEncoderCountAndStatus) {
  const LidarDataFormat f = make_format(UdpProfileLidar::kLegacy, 16, 16, 1024);
  const PacketFormat format(f);
  Scan scan(f);
  std::fill(scan.status.begin(), scan.status.end(), 0xFFFFFFFFu);
  scan.status[37] = 0;
  PacketHeader header;
  header.frame_id = 0x1234;
  std::vector<uint8_t> packet(format.lidar_packet_size());
  format.encode(header, scan, 32, packet);
  const size_t column_bytes = 16 + 12 * 16 + 4;
  for (size_t i = 0; i < 16; ++i) {
    const uint8_t* col = packet.data() + i * column_bytes;
    uint16_t m = 0, frame = 0;
    uint32_t encoder = 0, status = 0;
    std::memcpy(&m, col + 8, 2);
    std::memcpy(&frame, col + 10, 2);
    std::memcpy(&encoder, col + 12, 4);
    std::memcpy(&status, col + column_bytes - 4, 4);
    EXPECT_EQ(m, 32 + i);
    EXPECT_EQ(frame, 0x1234);
    EXPECT_EQ(encoder, 88u * m);  // protocol doc 4.2: 90112 / 1024 = 88 ticks per column
    EXPECT_EQ(status, m == 37 ? 0u : 0xFFFFFFFFu);
  }
}

// Every profile x H x columns_per_packet; combinations over 65535 bytes must be refused.
TEST(Packet, RoundTripsEveryProfileRandomized) {
  // Fixed seed: a failure must reproduce exactly; the values only need to cover every bit.
  std::mt19937_64 rng(20240611);
  for (UdpProfileLidar profile : kProfiles) {
    for (int height : {8, 16, 32, 64, 128}) {
      for (int cpp : {1, 4, 16, 64}) {
        const LidarDataFormat f = make_format(profile, height, cpp, 512);
        std::unique_ptr<PacketFormat> format;
        try {
          format = std::make_unique<PacketFormat>(f);
        } catch (const InputError&) {
          EXPECT_GT(test::doc_packet_size(profile, height, cpp), 65535u)
              << to_string(profile) << " " << height << " " << cpp;
          continue;
        }
        ASSERT_EQ(format->lidar_packet_size(), test::doc_packet_size(profile, height, cpp));
        test::expect_round_trip(*format, profile, rng);
      }
    }
  }
}

TEST(Crc64, CheckValueAndBitwiseReference) {
  const std::string check = "123456789";
  EXPECT_EQ(crc64_xz({reinterpret_cast<const uint8_t*>(check.data()), check.size()}), 0x995DC9BBDF1939FAull);
  EXPECT_EQ(crc64_xz({}), 0u);
  std::mt19937_64 rng(7);  // fixed seed: reproducible data, any values do
  std::vector<uint8_t> data(300);
  for (auto& b : data) b = static_cast<uint8_t>(rng());
  for (size_t start = 0; start < 8; ++start) {
    for (size_t length = 0; length + start <= data.size(); length += 7) {
      const std::span<const uint8_t> bytes(data.data() + start, length);
      ASSERT_EQ(crc64_xz(bytes), test::crc64_bitwise(bytes)) << "start " << start << " length " << length;
    }
  }
}

// At packet sizes (short, OS-32 and OS-128 packets), where a fast CRC folds blocks; a flipped bit
// anywhere must change it.
TEST(Crc64, PacketSizesMatchBitwiseReference) {
  std::mt19937_64 rng(11);  // fixed seed: reproducible data, any values do
  std::vector<uint8_t> data(25000);
  for (auto& b : data) b = static_cast<uint8_t>(rng());
  for (const size_t length : {3328u, 8448u, 24832u, 24999u}) {
    std::span<uint8_t> bytes(data.data(), length);
    const uint64_t before = crc64_xz(bytes);
    EXPECT_EQ(before, test::crc64_bitwise(bytes)) << "length " << length;
    bytes[length / 3] ^= 0x10;
    EXPECT_NE(crc64_xz(bytes), before) << "length " << length;
    EXPECT_EQ(crc64_xz(bytes), test::crc64_bitwise(bytes)) << "length " << length;
  }
}

TEST(Packet, FooterKindsRoundTripAndCorruptionFailsCrc) {
  const LidarDataFormat f = make_format(UdpProfileLidar::kRng15Rfl8Nir8, 32, 16);
  const PacketFormat format(f);
  Scan scan(f);
  std::mt19937_64 rng(3);  // fixed seed: reproducible data, any values do
  test::fill_random(scan, UdpProfileLidar::kRng15Rfl8Nir8, rng);
  std::vector<uint8_t> packet(format.lidar_packet_size());
  std::string error;
  const std::array<uint8_t, 8> marker{0xde, 0xc0, 0x00, 0x00, 0xef, 0xbe, 0xad, 0xde};
  format.encode(PacketHeader{}, scan, 0, packet, FooterKind::kFw2Marker);
  EXPECT_TRUE(std::equal(marker.begin(), marker.end(), packet.end() - 8));
  auto decoded = format.decode(packet, scan, &error);
  ASSERT_TRUE(decoded) << error;
  EXPECT_EQ(decoded->footer, FooterKind::kFw2Marker);
  EXPECT_TRUE(decoded->crc_ok);
  format.encode(PacketHeader{}, scan, 0, packet, FooterKind::kZero);
  EXPECT_TRUE(std::all_of(packet.end() - 32, packet.end(), [](uint8_t b) { return b == 0; }));
  EXPECT_EQ(format.decode(packet, scan, &error)->footer, FooterKind::kZero);

  format.encode(PacketHeader{}, scan, 0, packet, FooterKind::kCrc64);
  decoded = format.decode(packet, scan, &error);
  EXPECT_EQ(decoded->footer, FooterKind::kCrc64);
  EXPECT_TRUE(decoded->crc_ok);
  packet[100] ^= 0x10;
  decoded = format.decode(packet, scan, &error);
  ASSERT_TRUE(decoded) << error;
  EXPECT_EQ(decoded->footer, FooterKind::kOther);
  EXPECT_FALSE(decoded->crc_ok);
}

// Protocol doc 6.4: the three real metadata files the formula was fitted to.
TEST(ColumnWindow, MatchesRealMetadataExamples) {
  using Window = std::array<int, 2>;
  EXPECT_EQ(column_window_from_azimuth_window(180000, 360000, 512), (Window{1, 256}));
  EXPECT_EQ(column_window_from_azimuth_window(300000, 100000, 512), (Window{370, 85}));
  EXPECT_EQ(column_window_from_azimuth_window(583, 39402, 1024), (Window{912, 1022}));
  EXPECT_EQ(column_window_from_azimuth_window(0, 360000, 1024), (Window{0, 1023}));
  EXPECT_TRUE(column_in_window({370, 85}, 511));
  EXPECT_TRUE(column_in_window({370, 85}, 0));
  EXPECT_FALSE(column_in_window({370, 85}, 86));
  EXPECT_FALSE(column_in_window({1, 256}, 0));
  EXPECT_TRUE(column_in_window({1, 256}, 256));
}

TEST(ColumnWindow, PacketsPerFrameMatchRealCaptures) {
  auto f = make_format(UdpProfileLidar::kRng15Rfl8Nir8, 128, 16, 512);
  f.column_window = {1, 256};
  EXPECT_EQ(PacketFormat(f).packets_per_frame(), 17);  // windowed_frame1.pcap
  f.column_window = {370, 85};
  EXPECT_EQ(PacketFormat(f).packets_per_frame(), 15);  // windowed_frame2.pcap
  EXPECT_TRUE(PacketFormat(f).packet_in_window(368));
  EXPECT_FALSE(PacketFormat(f).packet_in_window(352));
  f.column_window = {0, 511};
  EXPECT_EQ(PacketFormat(f).packets_per_frame(), 32);
}

TEST(Packet, HostileInputGivesErrorsNotCrashes) {
  for (UdpProfileLidar profile : kProfiles) {
    const LidarDataFormat f = make_format(profile, 32, 16);
    const PacketFormat format(f);
    Scan scan(f);
    std::string error;
    std::vector<uint8_t> packet(format.lidar_packet_size() - 1);
    EXPECT_FALSE(format.decode(packet, scan, &error));
    EXPECT_NE(error.find(std::to_string(packet.size()) + " bytes, expected"), std::string::npos) << error;
    packet.resize(format.lidar_packet_size() + 1);
    EXPECT_FALSE(format.decode(packet, scan, &error));
    EXPECT_FALSE(format.decode({}, scan, nullptr));
    Scan wrong(make_format(profile, 16, 16));
    packet.resize(format.lidar_packet_size());
    EXPECT_FALSE(format.decode(packet, wrong, &error));
    EXPECT_NE(error.find("scan is 512x16"), std::string::npos) << error;
  }
}

TEST(Packet, RejectsNonLidarPacketTypeAndSkipsMeasurementIdsPastWidth) {
  const LidarDataFormat f = make_format(UdpProfileLidar::kRng19Rfl8Sig16Nir16, 16, 16);
  const PacketFormat format(f);
  Scan scan(f);
  std::vector<uint8_t> packet(format.lidar_packet_size());
  PacketHeader imu_header;
  imu_header.packet_type = 2;
  format.encode(imu_header, scan, 0, packet);
  std::string error;
  EXPECT_FALSE(format.decode(packet, scan, &error));
  EXPECT_NE(error.find("packet_type 2, expected 1"), std::string::npos) << error;

  std::fill(scan.status.begin(), scan.status.end(), 1u);
  format.encode(PacketHeader{}, scan, 496, packet);
  const uint16_t bad_m = 600;  // column 3 of the packet claims m = 600 >= W = 512
  std::memcpy(packet.data() + 32 + 3 * format.column_size() + 8, &bad_m, 2);
  Scan decoded(f);
  ASSERT_TRUE(format.decode(packet, decoded, &error)) << error;
  EXPECT_EQ(decoded.status[498], 1u);
  EXPECT_EQ(decoded.status[499], 0u);
  EXPECT_EQ(decoded.packet_received[31], 1u);
}

// Header bytes of real packets; the expected values are the captures' metadata (init_id, prod_sn)
// and protocol doc 4.3 (shot_limiting_test.pcap: countdown 5, thermal and shot limiting 1).
TEST(Packet, DecodesRealHeaderBytes) {
  const auto fusa = test::decode_header(UdpProfileLidar::kFusaRng15Rfl8Nir8Dual,
                                        "01bcf305e50000008c0000a5ee6d761c");  // OS-1-128_767798045 FUSA
  EXPECT_EQ(fusa.init_id, 390076u);
  EXPECT_EQ(fusa.frame_id, 229u);
  EXPECT_EQ(fusa.alert_flags, 0x8c);
  EXPECT_EQ(fusa.prod_sn, 122246000293u);
  const auto standard =
      test::decode_header(UdpProfileLidar::kRng19Rfl8Sig16Nir16, "01001825368ee6dd5df77f1c980000000500010100");
  EXPECT_EQ(standard.frame_id, 9496u);
  EXPECT_EQ(standard.init_id, 15109686u);
  EXPECT_EQ(standard.prod_sn, 122406002141u);
  EXPECT_EQ(standard.alert_flags, 0x98);
  EXPECT_EQ(standard.countdown_thermal_shutdown, 5);
  EXPECT_EQ(standard.countdown_shot_limiting, 0);
  EXPECT_EQ(standard.thermal_shutdown, 1);
  EXPECT_EQ(standard.shot_limiting, 1);
}

TEST(DataFormat, NamesRoundTripAndUnknownNamesAreRejected) {
  for (UdpProfileLidar p : kProfiles) EXPECT_EQ(udp_profile_lidar_from_string(to_string(p)), p);
  EXPECT_EQ(udp_profile_lidar_names().size(), kProfiles.size());
  EXPECT_EQ(to_string(UdpProfileLidar::kRng15Rfl8Nir8), "RNG15_RFL8_NIR8");
  EXPECT_FALSE(udp_profile_lidar_from_string("rng15_rfl8_nir8"));
  EXPECT_EQ(udp_profile_imu_from_string("ACCEL32_GYRO32_NMEA"), UdpProfileImu::kAccel32Gyro32Nmea);
  EXPECT_EQ(header_type_from_string("FUSA"), HeaderType::kFusa);
  EXPECT_EQ(to_string(ChannelField::kNearIr), "NEAR_IR");
  EXPECT_EQ(parse_lidar_mode("2048x10"), (LidarMode{2048, 10}));
  EXPECT_EQ(to_string(LidarMode{4096, 5}), "4096x5");
  for (const char* bad : {"", "1024", "1024x", "x10", "1000x10", "1024x15", "1024x10 ", "-512x10", "1024x+10"}) {
    EXPECT_FALSE(parse_lidar_mode(bad)) << bad;
  }
}

// The first IMU packet of OS-1-64_1024x10_fw20.pcap (protocol doc 5.1: at rest, z about +1 g).
TEST(ImuPacket, DecodesRealPacketAndRoundTrips) {
  const auto bytes = test::from_hex(
      "ea64eac6400000008aa8edc640000000d009f1c6400000000000ecbc0000b63c00007f3f007c12bf000aa53f005c41bf");
  const auto sample = decode_legacy_imu(bytes);
  ASSERT_TRUE(sample);
  EXPECT_EQ(sample->sys_ts_ns, 278215156970u);
  EXPECT_EQ(sample->gyro_ts_ns, 278215592400u);
  EXPECT_FLOAT_EQ(sample->accel_g[2], 0.99609375f);
  EXPECT_FLOAT_EQ(sample->gyro_deg_s[0], -0.57220458984375f);
  std::array<uint8_t, kLegacyImuPacketSize> out{};
  encode_legacy_imu(*sample, out);
  EXPECT_TRUE(std::equal(out.begin(), out.end(), bytes.begin()));
  EXPECT_FALSE(decode_legacy_imu(std::span(bytes).first(47)));
}

TEST(ImuPacket, NmeaProfileRoundTripsAndChecksItsInput) {
  EXPECT_EQ(nmea_imu_packet_size(8), 452u);  // protocol doc 5.2, imu_zm_no_lidar.pcap
  std::mt19937_64 rng(11);                   // fixed seed: reproducible values, any do
  std::uniform_real_distribution<float> value(-20.0f, 20.0f);
  NmeaImuPacket packet;
  packet.header = test::random_header(UdpProfileLidar::kRng19Rfl8Sig16Nir16, rng);
  packet.header.packet_type = 2;
  packet.nmea_timestamp_ns = rng();
  packet.nmea_sentence = "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A";
  for (uint16_t i = 0; i < 8; ++i) {
    packet.measurements.push_back({rng(),
                                   static_cast<uint16_t>(31 + 32 * i),
                                   1,
                                   {value(rng), value(rng), value(rng)},
                                   {value(rng), value(rng), value(rng)}});
  }
  for (HeaderType type : {HeaderType::kStandard, HeaderType::kFusa}) {
    std::vector<uint8_t> bytes(nmea_imu_packet_size(8));
    encode_nmea_imu(packet, type, bytes);
    std::string error;
    auto decoded = decode_nmea_imu(bytes, 8, type, &error);
    ASSERT_TRUE(decoded) << error;
    EXPECT_EQ(decoded->packet, packet);
    EXPECT_EQ(decoded->footer, FooterKind::kCrc64);
    uint64_t ts = 0;
    std::memcpy(&ts, bytes.data() + 132, 8);  // first measurement right after the NMEA block
    EXPECT_EQ(ts, packet.measurements[0].timestamp_ns);
    bytes[200] ^= 1;
    EXPECT_FALSE(decode_nmea_imu(bytes, 8, type, &error)->crc_ok);
    EXPECT_FALSE(decode_nmea_imu(bytes, 7, type, &error));
    EXPECT_NE(error.find("452 bytes, expected 416"), std::string::npos) << error;
    EXPECT_FALSE(decode_nmea_imu(bytes, 0, type, &error));
  }
  std::vector<uint8_t> lidar(nmea_imu_packet_size(8));
  lidar[0] = 1;
  std::string error;
  EXPECT_FALSE(decode_nmea_imu(lidar, 8, HeaderType::kStandard, &error));
  EXPECT_NE(error.find("packet_type 1, expected 2"), std::string::npos) << error;
}

}  // namespace
}  // namespace lidartwin
