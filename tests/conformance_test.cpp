// The packet codec against real sensors: every lidar packet of the sample captures
// (tests/data/ouster-samples, see its README) is decoded with its metadata and encoded again from
// the decoded scan, header and footer kind, and must come out byte for byte identical.
#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/pcap/pcap.h"

namespace lidartwin {
namespace {

const std::filesystem::path kSamples = std::filesystem::path(LIDARTWIN_TEST_DATA) / "ouster-samples";

// Packet counts, ports and windows from the samples' README and metadata; frame counts follow
// from them (W / 16 packets per frame). The footer is what each firmware puts in the last 8 bytes
// (protocol doc 4.5): FW 2.3/2.4 the marker, FW 2.2 and the FW 3.1 FUSA dev build zeros (the
// doc does not say FUSA footers are zero; the captures show it), FW 2.5 and 3.2 a CRC.
struct Sample {
  const char* pcap;
  const char* metadata;
  uint16_t port;
  int packets;
  int frames;
  int valid_columns;  // columns with status bit 0 set
  FooterKind footer;
};

constexpr FooterKind kMarker = FooterKind::kFw2Marker;
constexpr FooterKind kZero = FooterKind::kZero;
constexpr FooterKind kCrc = FooterKind::kCrc64;
constexpr FooterKind kNone = FooterKind::kNone;

const Sample kSamplesTable[] = {
    {"OS-0-128-U1_v2.3.0_1024x10.pcap", "OS-0-128-U1_v2.3.0_1024x10.json", 7502, 64, 1, 1024, kMarker},
    {"OS-0-32-U1_v2.2.0_1024x10.pcap", "OS-0-32-U1_v2.2.0_1024x10.json", 7502, 64, 1, 1024, kZero},
    {"OS-0-32-U1_v2.2.0_1024x10-single-packet.pcap", "OS-0-32-U1_v2.2.0_1024x10.json", 7502, 1, 1, 16, kZero},
    {"OS-1-128_767798045_1024x10_20230712_120049.pcap", "OS-1-128_767798045_1024x10_20230712_120049.json", 7502, 8, 1,
     128, kZero},
    {"OS-1-128_v2.3.0_1024x10_lb_n3.pcap", "OS-1-128_v2.3.0_1024x10.json", 7502, 192, 3, 3072, kMarker},
    {"OS-1-32-G_v2.1.1_1024x10.pcap", "OS-1-32-G_v2.1.1_1024x10.json", 7502, 64, 1, 1024, kNone},
    {"OS-1-64_1024x10_fw20.pcap", "OS-1-64_sensor_config_reduced.json", 7502, 64, 1, 1024, kNone},
    {"OS-2-128-U1_v2.3.0_1024x10.pcap", "OS-2-128-U1_v2.3.0_1024x10.json", 7502, 64, 1, 1024, kMarker},
    {"OS-2-32-U0_v2.0.0_1024x10.pcap", "OS-2-32-U0_v2.0.0_1024x10.json", 7502, 64, 1, 1024, kNone},
    {"crc_test.pcap", "crc_test.json", 7502, 34, 2, 544, kCrc},
    {"duplicate_id.pcap", "duplicate_id.json", 34636, 1, 1, 16, kMarker},
    {"same_ports.pcap", "same_ports.1.json", 7502, 1, 1, 16, kZero},
    {"same_ports.pcap", "same_ports.2.json", 7502, 1, 1, 16, kNone},
    {"same_ports_legacy.pcap", "same_ports_legacy.1.json", 7502, 1, 1, 16, kNone},
    {"same_ports_legacy.pcap", "same_ports_legacy.2.json", 7502, 1, 1, 16, kNone},
    {"same_ports_nonlegacy.pcap", "same_ports_nonlegacy.1.json", 7502, 1, 1, 16, kZero},
    {"same_ports_nonlegacy.pcap", "same_ports_nonlegacy.2.json", 7502, 1, 1, 16, kCrc},
    {"shot_limiting_test.pcap", "shot_limiting_test.json", 7702, 1, 1, 16, kCrc},
    {"windowed_frame1.pcap", "windowed_frame1_0.json", 53750, 17, 1, 256, kMarker},  // window [1, 256]
    {"windowed_frame2.pcap", "windowed_frame2_0.json", 53750, 15, 1, 228, kMarker},  // window [370, 85]
};

void PrintTo(const Sample& sample, std::ostream* os) { *os << sample.pcap << " with " << sample.metadata; }

struct Decoded {
  std::vector<uint8_t> bytes;
  PacketFormat::Decoded result;
};

// The sample's lidar packets: right port and size, and, where two sensors share a port (the
// same_ports captures), from the metadata's sensor (prod_sn in non-legacy headers).
std::vector<Decoded> decode_sample(const Sample& sample, const PacketFormat& format, const Metadata& metadata) {
  std::vector<Decoded> packets;
  Scan scan(format.format());
  for (UdpDatagram& d : read_pcap(kSamples / sample.pcap)) {
    if (d.dst_port != sample.port || d.payload.size() != format.lidar_packet_size()) continue;
    auto result = format.decode(d.payload, scan, nullptr);
    if (!result) continue;
    const bool legacy = format.format().udp_profile_lidar == UdpProfileLidar::kLegacy;
    if (!legacy && !metadata.sensor_info.prod_sn.empty() &&
        result->header.prod_sn != std::stoull(metadata.sensor_info.prod_sn)) {
      continue;
    }
    packets.push_back({std::move(d.payload), *result});
  }
  return packets;
}

class Conformance : public testing::TestWithParam<Sample> {};

TEST_P(Conformance, ReencodesEveryPacketByteExactly) {
  const Sample& sample = GetParam();
  const Metadata metadata = load_metadata(kSamples / sample.metadata);
  const PacketFormat format(metadata.format);
  const auto packets = decode_sample(sample, format, metadata);
  ASSERT_EQ(static_cast<int>(packets.size()), sample.packets);

  Scan scan(format.format());
  std::vector<uint8_t> encoded(format.lidar_packet_size());
  std::set<uint32_t> frames;
  int valid_columns = 0;
  for (size_t i = 0; i < packets.size(); ++i) {
    const auto& [bytes, first] = packets[i];
    ASSERT_TRUE(format.decode(bytes, scan, nullptr));
    EXPECT_EQ(first.footer, sample.footer) << "packet " << i;
    format.encode(first.header, scan, first.first_measurement_id, encoded, first.footer);
    const auto mismatch = std::mismatch(bytes.begin(), bytes.end(), encoded.begin());
    ASSERT_TRUE(mismatch.first == bytes.end())
        << "packet " << i << " differs first at byte " << (mismatch.first - bytes.begin());
    frames.insert(first.header.frame_id);
    for (int c = 0; c < format.format().columns_per_packet; ++c) {
      valid_columns += scan.status[static_cast<size_t>(first.first_measurement_id + c)] & 1;
    }
  }
  EXPECT_EQ(static_cast<int>(frames.size()), sample.frames);
  EXPECT_EQ(valid_columns, sample.valid_columns);
}

// One flipped bit anywhere before the footer breaks a real CRC; marker and zero footers carry none.
TEST_P(Conformance, CorruptedCopyFailsCrc) {
  const Sample& sample = GetParam();
  const Metadata metadata = load_metadata(kSamples / sample.metadata);
  const PacketFormat format(metadata.format);
  Scan scan(format.format());
  size_t position = 0;
  for (auto& [bytes, result] : decode_sample(sample, format, metadata)) {
    position = (position + 7919) % (bytes.size() - 8);
    bytes[position] ^= 0x01;
    const auto corrupted = format.decode(bytes, scan, nullptr);
    ASSERT_TRUE(corrupted);
    EXPECT_EQ(corrupted->crc_ok, sample.footer != kCrc);
    if (sample.footer == kCrc) {
      EXPECT_EQ(corrupted->footer, FooterKind::kOther);
    }
  }
}

std::string sample_name(const testing::TestParamInfo<Sample>& info) {
  std::string name = std::string(info.param.metadata);
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name + "_" + std::to_string(info.index);
}

INSTANTIATE_TEST_SUITE_P(Samples, Conformance, testing::ValuesIn(kSamplesTable), sample_name);

// Every 48-byte datagram on an IMU port of the LEGACY-IMU samples (protocol doc 5.1).
TEST(ImuConformance, LegacyPacketsReencodeByteExactly) {
  int packets = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kSamples)) {
    if (entry.path().extension() != ".pcap") continue;
    for (const UdpDatagram& d : read_pcap(entry.path())) {
      if (d.payload.size() != kLegacyImuPacketSize) continue;
      const auto sample = decode_legacy_imu(d.payload);
      ASSERT_TRUE(sample) << entry.path();
      std::array<uint8_t, kLegacyImuPacketSize> encoded{};
      encode_legacy_imu(*sample, encoded);
      ASSERT_TRUE(std::equal(encoded.begin(), encoded.end(), d.payload.begin())) << entry.path();
      ++packets;
    }
  }
  // README: 10 + 10 + 2 + 30 + 11 + 10 + 10 + 10 + 10 in the single-sensor captures (OS-0-128-U1,
  // OS-0-32-U1, OS-1-128 FUSA, OS-1-128 lb_n3, OS-1-64 fw20, OS-2-128-U1, crc_test, windowed 1
  // and 2), 2 + 2 in same_ports and same_ports_nonlegacy.
  EXPECT_EQ(packets, 107);
}

// imu_zm_no_lidar.pcap: FW 3.2, 8 IMU packets of 8 measurements on port 7513 with valid CRCs;
// measurement ids every W/64 = 32 columns starting at 31 (protocol doc 5.2).
TEST(ImuConformance, NmeaPacketsReencodeByteExactly) {
  const Metadata metadata = load_metadata(kSamples / "imu_zm_no_lidar_0.json");
  const int n = metadata.format.imu_measurements_per_packet;
  ASSERT_EQ(n, 8);
  int packets = 0;
  for (const UdpDatagram& d : read_pcap(kSamples / "imu_zm_no_lidar.pcap")) {
    if (d.dst_port != 7513) continue;
    std::string error;
    const auto decoded = decode_nmea_imu(d.payload, n, metadata.format.header_type, &error);
    ASSERT_TRUE(decoded) << error;
    EXPECT_EQ(decoded->footer, FooterKind::kCrc64);
    EXPECT_EQ(decoded->packet.header.init_id, metadata.sensor_info.initialization_id);
    EXPECT_EQ(decoded->packet.measurements[0].measurement_id % 32, 31);
    EXPECT_NEAR(decoded->packet.measurements[0].accel_m_s2[2], 9.8, 0.5);  // at rest, z up
    std::vector<uint8_t> encoded(d.payload.size());
    encode_nmea_imu(decoded->packet, metadata.format.header_type, encoded, decoded->footer);
    ASSERT_EQ(encoded, d.payload) << "packet " << packets;
    ++packets;
  }
  EXPECT_EQ(packets, 8);
}

}  // namespace
}  // namespace lidartwin
