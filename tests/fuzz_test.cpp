// Hostile bytes for every decoder. tools/test reruns the suites named Fuzz* under AddressSanitizer
// and UBSan (Debug, asserts on), so a test passes only if nothing reads out of bounds or trips an
// invariant. One suite per decoder: FuzzPacket (lidar), FuzzImuPacket; metadata, pcap and OSF
// suites follow the same pattern.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/error.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/pcap/osf.h"
#include "lidartwin/pcap/pcap.h"
#include "packet_test_util.h"
#include "support/raw_pcap.h"

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

// ---- FuzzMetadata: hostile JSON documents. Every input must parse or fail with InputError; any
// other exception (a nlohmann type_error from an unchecked access) or a crash is a bug. A document
// that parses must also round-trip through to_nested_json.

const std::filesystem::path kOusterSamples = std::filesystem::path(LIDARTWIN_TEST_DATA) / "ouster-samples";

std::vector<std::filesystem::path> metadata_samples() {
  std::vector<std::filesystem::path> files;
  for (const auto& dir : {kOusterSamples, kOusterSamples / "metadata"}) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.path().extension() == ".json") files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

nlohmann::json random_value(std::mt19937_64& rng, int depth) {
  static const char* const kKeys[] = {"sensor_info",       "beam_intrinsics", "lidar_mode",
                                      "prod_line",         "data_format",     "beam_altitude_angles",
                                      "pixels_per_column", "column_window",   "udp_dest"};
  switch (rng() % (depth > 2 ? 5 : 7)) {
    case 0: return nullptr;
    case 1: return rng() % 2 == 0;
    case 2: return static_cast<int64_t>(rng()) >> (rng() % 64);
    case 3: return std::ldexp(static_cast<double>(static_cast<int64_t>(rng())), static_cast<int>(rng() % 200) - 100);
    case 4: return std::string(kKeys[rng() % std::size(kKeys)]).substr(0, rng() % 12);
    case 5: {
      nlohmann::json array = nlohmann::json::array();
      for (size_t n = rng() % 70; n > 0; --n) array.push_back(random_value(rng, depth + 1));
      return array;
    }
    default: {
      nlohmann::json object = nlohmann::json::object();
      for (size_t n = rng() % 6; n > 0; --n) object[kKeys[rng() % std::size(kKeys)]] = random_value(rng, depth + 1);
      return object;
    }
  }
}

void collect_pointers(const nlohmann::json& value, const nlohmann::json::json_pointer& at,
                      std::vector<nlohmann::json::json_pointer>& out) {
  out.push_back(at);
  if (value.is_object()) {
    for (const auto& [key, child] : value.items()) collect_pointers(child, at / key, out);
  } else if (value.is_array()) {
    for (size_t i = 0; i < value.size(); ++i) collect_pointers(value[i], at / i, out);
  }
}

// Replaces, deletes or truncates one node anywhere in the document.
void mutate(nlohmann::json& document, std::mt19937_64& rng) {
  std::vector<nlohmann::json::json_pointer> pointers;
  collect_pointers(document, nlohmann::json::json_pointer(), pointers);
  const auto& target = pointers[rng() % pointers.size()];
  nlohmann::json& node = document[target];
  const int action = static_cast<int>(rng() % 3);
  if (action == 0 || target.empty()) {
    node = random_value(rng, 1);
  } else if (action == 1) {
    nlohmann::json& parent = document[target.parent_pointer()];
    if (parent.is_object()) parent.erase(target.back());
    if (parent.is_array()) parent.erase(parent.size() - 1);
  } else if (node.is_array() && !node.empty()) {
    node.erase(rng() % node.size());
  }
}

// Parses or throws InputError; anything else fails the test.
void expect_parses_or_input_error(const nlohmann::json& document) {
  try {
    const Metadata m = parse_metadata(document, "fuzz.json");
    EXPECT_EQ(parse_metadata(to_nested_json(m), "round trip"), m) << document.dump().substr(0, 300);
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fuzz.json: /"), std::string::npos) << e.what();
  }
}

TEST(FuzzMetadata, MutatedSamplesParseOrFailCleanly) {
  std::mt19937_64 rng(31);  // fixed seed: a crash must reproduce
  for (const auto& file : metadata_samples()) {
    std::ifstream in(file);
    const nlohmann::json original = nlohmann::json::parse(in);
    for (int trial = 0; trial < 25; ++trial) {
      nlohmann::json document = original;
      for (int mutations = 1 + static_cast<int>(rng() % 3); mutations > 0; --mutations) mutate(document, rng);
      SCOPED_TRACE(file.filename().string());
      expect_parses_or_input_error(document);
    }
  }
}

TEST(FuzzMetadata, RandomDocumentsParseOrFailCleanly) {
  std::mt19937_64 rng(32);  // fixed seed: a crash must reproduce
  for (int trial = 0; trial < 2000; ++trial) expect_parses_or_input_error(random_value(rng, 0));
}

TEST(FuzzMetadata, TruncatedFilesAreInputErrors) {
  std::mt19937_64 rng(33);  // fixed seed: a crash must reproduce
  const auto path = std::filesystem::temp_directory_path() / ("lidartwin_fuzz_" + std::to_string(getpid()) + ".json");
  for (const auto& file : metadata_samples()) {
    std::ifstream in(file);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(path) << text.substr(0, rng() % text.rfind('}'));  // always before the closing brace
    EXPECT_THROW(load_metadata(path), InputError) << file;
  }
  std::filesystem::remove(path);
}

// ---- FuzzPcap: hostile capture files. read_pcap must return or throw InputError, never crash,
// and never return a datagram larger than UDP allows.

void expect_reads_or_input_error(const std::filesystem::path& path) {
  try {
    for (const UdpDatagram& d : read_pcap(path)) ASSERT_LE(d.payload.size(), 65507u);
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST(FuzzPcap, TruncatedCapturesReadOrFailCleanly) {
  const auto bytes = test::read_bytes(kOusterSamples / "same_ports.pcap");  // IP-fragmented
  test::TempFile file(".pcap");
  for (size_t length = 0; length < bytes.size(); length += 1 + length / 8) {
    file.write({bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(length)});
    expect_reads_or_input_error(file.path());
  }
}

// Offsets of the records of a classic pcap (record header, then frame).
std::vector<size_t> record_offsets(const std::vector<uint8_t>& bytes) {
  std::vector<size_t> offsets;
  for (size_t at = 24; at + 16 <= bytes.size();) {
    offsets.push_back(at);
    at += 16 + (bytes[at + 8] | bytes[at + 9] << 8 | bytes[at + 10] << 16 | static_cast<size_t>(bytes[at + 11]) << 24);
  }
  return offsets;
}

TEST(FuzzPcap, CorruptedHeadersReadOrFailCleanly) {
  std::mt19937_64 rng(41);                                                     // fixed seed: a crash must reproduce
  const auto original = test::read_bytes(kOusterSamples / "same_ports.pcap");  // IP-fragmented
  const std::vector<size_t> records = record_offsets(original);
  test::TempFile file(".pcap");
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<uint8_t> bytes = original;
    // The first 58 bytes of a record: pcap record, Ethernet, IPv4 and UDP headers.
    for (int changes = 1 + static_cast<int>(rng() % 6); changes > 0; --changes) {
      const size_t at = records[rng() % records.size()] + rng() % 58;
      bytes[at] = static_cast<uint8_t>(rng());
    }
    file.write(bytes);
    expect_reads_or_input_error(file.path());
  }
}

TEST(FuzzPcap, RandomBytesReadOrFailCleanly) {
  std::mt19937_64 rng(42);  // fixed seed: a crash must reproduce
  test::TempFile file(".pcap");
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> bytes = trial % 2 ? test::raw_pcap({}) : std::vector<uint8_t>{};
    for (size_t n = rng() % 3000; n > 0; --n) bytes.push_back(static_cast<uint8_t>(rng()));
    file.write(bytes);
    expect_reads_or_input_error(file.path());
  }
}

// Random fragments of a few datagrams: overlapping, duplicated, disagreeing, past 64 KiB.
TEST(FuzzPcap, FragmentSoupReadsOrFailsCleanly) {
  std::mt19937_64 rng(43);  // fixed seed: a crash must reproduce
  test::TempFile file(".pcap");
  for (int trial = 0; trial < 100; ++trial) {
    std::vector<test::RawRecord> records;
    for (int n = 0; n < 60; ++n) {
      test::IpFields ip;
      ip.id = static_cast<uint16_t>(rng() % 3);
      ip.offset = static_cast<uint32_t>(rng() % 8192) * 8 % (rng() % 2 ? 4000 : 65536);
      ip.more_fragments = rng() % 3 != 0;
      std::vector<uint8_t> payload(rng() % 1480, static_cast<uint8_t>(rng() % 2));
      if (ip.offset == 0 && payload.size() >= 8)
        payload = test::udp_bytes(1, 2, std::vector<uint8_t>(payload.size() - 8));
      records.push_back({static_cast<uint32_t>(trial), static_cast<uint32_t>(n), test::ipv4_frame(ip, payload)});
    }
    file.write(test::raw_pcap(records));
    expect_reads_or_input_error(file.path());
  }
}

// ---- FuzzOsf: hostile OSF files. OsfReader must read to the end or throw InputError naming the
// file, never crash. Every block ends with a CRC-32 that would stop most damage at the door, so
// the mutated files get their CRCs made right again: the damage reaches the flatbuffer tables and
// the field images behind them.

uint32_t osf_crc32(const uint8_t* data, size_t size) {
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < size; ++i) {
    crc ^= data[i];
    for (int k = 0; k < 8; ++k) crc = (crc & 1u) ? (crc >> 1) ^ 0xEDB88320u : crc >> 1;
  }
  return ~crc;
}

uint32_t little32_at(const std::vector<uint8_t>& bytes, size_t at) {
  return bytes[at] | bytes[at + 1] << 8 | bytes[at + 2] << 16 | static_cast<uint32_t>(bytes[at + 3]) << 24;
}

// The OSF blocks, [u32 size][size bytes][u32 CRC]: header, chunks and metadata follow each other.
std::vector<std::pair<size_t, size_t>> osf_blocks(const std::vector<uint8_t>& bytes) {
  std::vector<std::pair<size_t, size_t>> blocks;  // (offset, size)
  for (size_t at = 0; at + 4 <= bytes.size();) {
    const size_t size = little32_at(bytes, at);
    if (at + 8 + size > bytes.size()) break;
    blocks.emplace_back(at, size);
    at += 8 + size;
  }
  return blocks;
}

void expect_osf_reads_or_input_error(const std::filesystem::path& path) {
  try {
    OsfReader reader(path);
    while (auto scan = reader.next()) {
      for (const OsfImage& image : scan->images) {
        ASSERT_EQ(image.values.size(), static_cast<size_t>(scan->width) * static_cast<size_t>(scan->height));
      }
    }
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST(FuzzOsf, MutatedRecordingsReadOrFailCleanly) {
  std::mt19937_64 rng(43);  // fixed seed: a crash must reproduce
  // One ZPNG scan, the smallest real recording: its tables, then nine field images.
  const auto original = test::read_bytes(kOusterSamples / "osfs" / "single_scan_016.osf");
  const auto blocks = osf_blocks(original);
  ASSERT_EQ(blocks.size(), 3u) << "header, one chunk, metadata";
  test::TempFile file(".osf");
  // 60 trials: each decodes nine field images, about 0.3 s under the sanitizers' Debug build.
  for (int trial = 0; trial < 60; ++trial) {
    std::vector<uint8_t> bytes = original;
    for (int changes = 1 + static_cast<int>(rng() % 4); changes > 0; --changes) {
      // The chunk (tables and images) most often, the metadata less, the small header rarely: any
      // change there stops the read before the rest is seen. Half the chunk's and metadata's damage
      // lands in their first or last 2 KiB, where their tables are.
      const size_t roll = rng() % 20;
      const auto [offset, size] = blocks[roll == 0 ? 0 : roll < 13 ? 1 : 2];
      const size_t span = size + 8, edge = std::min<size_t>(span, 2048);
      size_t at = offset + rng() % span;
      if (rng() % 2) at = rng() % 2 ? offset + rng() % edge : offset + span - 1 - rng() % edge;
      bytes[at] = static_cast<uint8_t>(rng());
    }
    for (const auto& [offset, size] : blocks) {
      const uint32_t crc = osf_crc32(bytes.data() + offset, 4 + size);
      for (int k = 0; k < 4; ++k)
        bytes[offset + 4 + size + static_cast<size_t>(k)] = static_cast<uint8_t>(crc >> (8 * k));
    }
    file.write(bytes);
    expect_osf_reads_or_input_error(file.path());
  }
}

TEST(FuzzOsf, TruncatedRecordingsFailCleanly) {
  const auto bytes = test::read_bytes(kOusterSamples / "osfs" / "single_scan_016.osf");
  test::TempFile file(".osf");
  for (size_t length = 0; length < bytes.size(); length += 1 + length / 4) {
    file.write({bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(length)});
    expect_osf_reads_or_input_error(file.path());
  }
}

}  // namespace
}  // namespace lidartwin
