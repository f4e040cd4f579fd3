// pcap: reading real Ouster captures (with IPv4 reassembly), writing captures a real reader accepts.
#include "lidartwin/pcap/pcap.h"

#include <map>
#include <random>
#include <string>
#include <utility>

#include <gtest/gtest.h>

#include "lidartwin/error.h"
#include "support/raw_pcap.h"

namespace lidartwin {
namespace {

using test::IpFields;
using test::RawRecord;
using test::TempFile;

const std::filesystem::path kSamples = std::filesystem::path(LIDARTWIN_TEST_DATA) / "ouster-samples";

using PortSizeCounts = std::map<std::pair<uint16_t, size_t>, int>;  // (dst port, bytes) -> count

PortSizeCounts count_by_port_and_size(const std::vector<UdpDatagram>& datagrams) {
  PortSizeCounts counts;
  for (const UdpDatagram& d : datagrams) ++counts[{d.dst_port, d.payload.size()}];
  return counts;
}

struct SampleCounts {
  const char* file;
  PortSizeCounts expected;
  size_t incomplete = 0;  // fragment sets that never complete
  friend void PrintTo(const SampleCounts& sample, std::ostream* out) { *out << sample.file; }
};

// The table of tests/data/ouster-samples/README.md (from the shared sample README), not the
// reader's own output.
const SampleCounts kReadmeTable[] = {
    {"OS-0-128-U1_v2.3.0_1024x10.pcap", {{{7502, 8448}, 64}, {{7503, 48}, 10}}},
    {"OS-0-32-U1_v2.2.0_1024x10.pcap", {{{7502, 8448}, 64}, {{7503, 48}, 10}}},
    {"OS-0-32-U1_v2.2.0_1024x10-single-packet.pcap", {{{7502, 8448}, 1}}},
    {"OS-1-128_767798045_1024x10_20230712_120049.pcap", {{{7502, 16640}, 8}, {{7503, 48}, 2}}},
    {"OS-1-128_v2.3.0_1024x10_lb_n3.pcap", {{{7502, 8448}, 192}, {{7503, 48}, 30}}},
    {"OS-1-32-G_v2.1.1_1024x10.pcap", {{{7502, 6464}, 64}}},
    {"OS-1-64_1024x10_fw20.pcap", {{{7502, 12608}, 64}, {{7503, 48}, 11}}},
    {"OS-2-128-U1_v2.3.0_1024x10.pcap", {{{7502, 24832}, 64}, {{7503, 48}, 10}}},
    {"OS-2-32-U0_v2.0.0_1024x10.pcap", {{{7502, 6464}, 64}}},
    {"crc_test.pcap", {{{7502, 8448}, 34}, {{7503, 48}, 10}}},
    // Its first record is a lone first fragment 88 s older than the datagram that reuses its IP id
    // (the 16-bit id wrapped): it must expire, not poison the later set.
    {"duplicate_id.pcap", {{{34636, 8448}, 1}}, 1},
    {"imu_zm_no_lidar.pcap", {{{7513, 452}, 8}, {{7514, 680}, 1}}},
    // Two sensors on one port: OS-0-128 FUSA (16640 B) and OS-1-64-AH LEGACY (12608 B), IMU 48 B.
    {"same_ports.pcap", {{{7502, 48}, 2}, {{7502, 12608}, 1}, {{7502, 16640}, 1}}},
    // OS-0-128 LEGACY (24896 B) + OS-1-64-AH LEGACY (12608 B).
    {"same_ports_legacy.pcap", {{{7502, 12608}, 1}, {{7502, 24896}, 1}}},
    // OS-0-128 FUSA dual (16640 B) + OS-1-64-AH RNG19 DUAL at 64 beams (16640 B), 2 IMU.
    {"same_ports_nonlegacy.pcap", {{{7502, 48}, 2}, {{7502, 16640}, 2}}},
    {"shot_limiting_test.pcap", {{{7702, 24832}, 1}}},
    {"windowed_frame1.pcap", {{{53750, 8448}, 17}, {{7503, 48}, 10}}},
    {"windowed_frame2.pcap", {{{53750, 8448}, 15}, {{7503, 48}, 10}}},
};

class PcapSample : public testing::TestWithParam<SampleCounts> {};

TEST_P(PcapSample, ReadsTheReadmeDatagramCounts) {
  PcapStats stats;
  const auto datagrams = read_pcap(kSamples / GetParam().file, stats);
  EXPECT_EQ(count_by_port_and_size(datagrams), GetParam().expected);
  EXPECT_EQ(stats.datagrams, datagrams.size());
  EXPECT_EQ(stats.incomplete_datagrams, GetParam().incomplete);
  EXPECT_EQ(stats.conflicting_datagrams, 0u);
  EXPECT_EQ(stats.truncated_frames, 0u);
}

TEST_P(PcapSample, StreamingReaderMatchesReadPcap) {
  const auto all = read_pcap(kSamples / GetParam().file);
  PcapReader reader(kSamples / GetParam().file);
  size_t n = 0;
  while (auto datagram = reader.next()) {
    ASSERT_LT(n, all.size());
    EXPECT_EQ(*datagram, all[n++]);
  }
  EXPECT_EQ(n, all.size());
  EXPECT_FALSE(reader.next());  // stays at the end
}

TEST_P(PcapSample, RewrittenCaptureReadsBackIdentical) {
  auto original = read_pcap(kSamples / GetParam().file);
  for (UdpDatagram& d : original) d.timestamp_ns -= d.timestamp_ns % 1000;  // already µs files
  TempFile file(".pcap");
  {
    PcapWriter writer(file.path());
    for (const UdpDatagram& d : original) writer.write(d);
  }
  EXPECT_EQ(read_pcap(file.path()), original);
}

INSTANTIATE_TEST_SUITE_P(Samples, PcapSample, testing::ValuesIn(kReadmeTable),
                         [](const testing::TestParamInfo<SampleCounts>& param) {
                           std::string name = param.param.file;
                           for (char& c : name) c = std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
                           return name;
                         });

TEST(Pcap, ReassemblesTheFragmentedSample) {
  // duplicate_id.pcap: one 8448-byte lidar packet in 6 IPv4 fragments from an ephemeral port,
  // after a stale first fragment with the same IP id.
  PcapStats stats;
  const auto datagrams = read_pcap(kSamples / "duplicate_id.pcap", stats);
  ASSERT_EQ(datagrams.size(), 1u);
  EXPECT_EQ(stats.records, 7u);
  EXPECT_EQ(stats.fragments, 7u);
  EXPECT_EQ(datagrams[0].src_port, 50474);
  EXPECT_EQ(datagrams[0].dst_port, 34636);
  EXPECT_EQ(stats.incomplete_datagrams, 1u);
}

TEST(Pcap, DecodesAddressesAndTimestampsOfTheSample) {
  const auto datagrams = read_pcap(kSamples / "OS-0-32-U1_v2.2.0_1024x10-single-packet.pcap");
  ASSERT_EQ(datagrams.size(), 1u);
  EXPECT_EQ(datagrams[0].src_port, 7502);
  EXPECT_EQ(datagrams[0].timestamp_ns % 1000, 0u);                     // a microsecond file
  EXPECT_GT(datagrams[0].timestamp_ns, 1'000'000'000'000'000'000ULL);  // after 2001
}

UdpDatagram random_datagram(std::mt19937& rng, size_t size) {
  UdpDatagram d;
  d.timestamp_ns = (1'700'000'000'000'000ULL + rng() % 1'000'000'000ULL) * 1000;
  d.src_ip = {192, 168, 1, static_cast<uint8_t>(rng())};
  d.dst_ip = {192, 168, 1, 100};
  d.src_port = static_cast<uint16_t>(rng());
  d.dst_port = 7502;
  d.payload.resize(size);
  for (auto& b : d.payload) b = static_cast<uint8_t>(rng());
  return d;
}

TEST(PcapWriter, RoundTripsDatagramsOfEverySizeClass) {
  std::mt19937 rng(20240611);  // fixed seed: the sizes below matter, the bytes only need to differ
  // 1472 fills one 1500-byte frame exactly, 1473 is the first that fragments, 65507 is the UDP max.
  const size_t sizes[] = {0, 1, 48, 1472, 1473, 2952, 2953, 8448, 24896, 65507};
  std::vector<UdpDatagram> written;
  for (size_t size : sizes) written.push_back(random_datagram(rng, size));
  TempFile file(".pcap");
  {
    PcapWriter writer(file.path());
    for (const UdpDatagram& d : written) writer.write(d);
  }
  PcapStats stats;
  EXPECT_EQ(read_pcap(file.path(), stats), written);
  EXPECT_EQ(stats.incomplete_datagrams, 0u);
}

TEST(PcapWriter, AFullDiskIsAnErrorNamingTheFile) {
  try {
    PcapWriter writer("/dev/full");
    std::mt19937 rng(1);
    writer.write(random_datagram(rng, 24896));
    FAIL() << "writing to /dev/full succeeded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/full: cannot write capture: No space left on device"), std::string::npos)
        << e.what();
  }
}

// `record`'s way: staged in 4 MiB blocks written with O_DIRECT. 300 lidar-packet-sized datagrams
// (7.5 MB) cross a block boundary mid-record and leave an unaligned tail: the same datagrams come
// back, byte for byte the file the unbuffered writer makes.
TEST(PcapWriter, WritingInBlocksMakesTheSameFile) {
  std::mt19937 rng(20261125);
  std::vector<UdpDatagram> written;
  for (int i = 0; i < 300; ++i) written.push_back(random_datagram(rng, i % 50 == 0 ? 48 : 24896));
  TempFile blocks(".pcap"), each(".pcap");
  PcapWriter block_writer(blocks.path(), PcapFlush::kInBlocks);
  {
    PcapWriter writer(each.path());
    for (const UdpDatagram& d : written) block_writer.write(d), writer.write(d);
  }
  EXPECT_LT(std::filesystem::file_size(blocks.path()), 7'000'000u) << "staged, not yet written";
  block_writer.close();
  EXPECT_EQ(read_pcap(blocks.path()), written);
  EXPECT_EQ(test::read_bytes(blocks.path()), test::read_bytes(each.path()));
  block_writer.close();  // a second close does nothing
}

TEST(PcapWriter, AFullDiskIsAnErrorNamingTheFileWhenWritingInBlocks) {
  PcapWriter writer("/dev/full", PcapFlush::kInBlocks);
  std::mt19937 rng(1);
  const UdpDatagram d = random_datagram(rng, 24896);
  try {
    for (int i = 0; i < 400; ++i) writer.write(d);  // 10 MB: a failed block is reported here
    writer.close();                                 // or here
    FAIL() << "writing to /dev/full succeeded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/full: cannot write capture: No space left on device"), std::string::npos)
        << e.what();
  }
}

TEST(PcapWriter, StoresMicrosecondTimestamps) {
  UdpDatagram d;
  d.timestamp_ns = 1'690'000'000'123'456'789ULL;
  d.payload = {1, 2, 3};
  TempFile file(".pcap");
  {
    PcapWriter writer(file.path());
    writer.write(d);
  }
  EXPECT_EQ(read_pcap(file.path()).at(0).timestamp_ns, 1'690'000'000'123'456'000ULL);
}

// Reads the written bytes directly (not through the reader under test): frame sizes, IPv4
// lengths, fragment offsets and flags, and header checksums.
TEST(PcapWriter, FragmentsAtTheMtuLikeARealSender) {
  UdpDatagram d;
  d.payload.assign(8448, 0xAB);
  TempFile file(".pcap");
  {
    PcapWriter writer(file.path());
    writer.write(d);
  }
  const std::vector<uint8_t> bytes = test::read_bytes(file.path());
  ASSERT_GE(bytes.size(), 24u);
  size_t at = 24;
  size_t expected_offset = 0;
  int frames = 0;
  while (at + 16 <= bytes.size()) {
    const uint32_t caplen = bytes[at + 8] | bytes[at + 9] << 8 | bytes[at + 10] << 16 | bytes[at + 11] << 24;
    const uint8_t* frame = &bytes[at + 16];
    const uint8_t* ip = frame + 14;
    const size_t total = static_cast<size_t>(ip[2] << 8 | ip[3]);
    const size_t flags_offset = static_cast<size_t>(ip[6] << 8 | ip[7]);
    EXPECT_LE(caplen, 1514u);
    EXPECT_EQ(caplen, 14 + total);
    EXPECT_EQ((flags_offset & 0x1FFF) * 8, expected_offset);
    uint32_t sum = 0;
    for (int i = 0; i < 20; i += 2) sum += static_cast<uint32_t>(ip[i] << 8 | ip[i + 1]);
    while (sum >> 16) sum = (sum & 0xFFFF) + (sum >> 16);
    EXPECT_EQ(sum, 0xFFFFu) << "IPv4 header checksum of frame " << frames;
    expected_offset += total - 20;
    const bool last = expected_offset == 8 + 8448;
    EXPECT_EQ((flags_offset & 0x2000) != 0, !last);
    at += 16 + caplen;
    ++frames;
  }
  EXPECT_EQ(frames, 6);  // ceil((8 + 8448) / 1480)
  EXPECT_EQ(expected_offset, 8u + 8448u);
}

// The UDP checksum (RFC 768: pseudo-header, UDP header and payload, the odd byte padded) of every
// datagram written, both ways of writing, summed here byte pair by byte pair from the file's
// fragments reassembled by hand (Wireshark flags a wrong one when it validates them).
TEST(PcapWriter, UdpChecksumsVerify) {
  std::mt19937 rng(7);
  std::vector<UdpDatagram> written;
  for (const size_t size : {1, 2, 3, 47, 1471, 1472, 1473, 8449, 24896, 24897, 65507}) {
    written.push_back(random_datagram(rng, size));
    written.back().src_ip = {10, 5, 5, 87};
    written.back().src_port = 7502;
  }
  for (const PcapFlush flush : {PcapFlush::kEachDatagram, PcapFlush::kInBlocks}) {
    TempFile file(".pcap");
    {
      PcapWriter writer(file.path(), flush);
      for (const UdpDatagram& d : written) writer.write(d);
      writer.close();
    }
    const std::vector<uint8_t> bytes = test::read_bytes(file.path());
    std::vector<uint8_t> ip_payload;  // the datagram being reassembled: UDP header + payload
    size_t datagrams = 0;
    for (size_t at = 24; at + 16 <= bytes.size();) {
      const uint32_t caplen = bytes[at + 8] | bytes[at + 9] << 8 | bytes[at + 10] << 16 | bytes[at + 11] << 24;
      const uint8_t* ip = &bytes[at + 16 + 14];
      const size_t total = static_cast<size_t>(ip[2] << 8 | ip[3]);
      const size_t flags_offset = static_cast<size_t>(ip[6] << 8 | ip[7]);
      ip_payload.resize((flags_offset & 0x1FFF) * 8);
      ip_payload.insert(ip_payload.end(), ip + 20, ip + total);
      at += 16 + caplen;
      if ((flags_offset & 0x2000) != 0) continue;  // more fragments follow
      uint32_t sum = 0;
      for (int i = 12; i < 20; i += 2) sum += static_cast<uint32_t>(ip[i] << 8 | ip[i + 1]);  // the addresses
      sum += 17 + static_cast<uint32_t>(ip_payload.size());                                   // protocol, length
      for (size_t i = 0; i < ip_payload.size(); i += 2) {
        sum += static_cast<uint32_t>(ip_payload[i] << 8 | (i + 1 < ip_payload.size() ? ip_payload[i + 1] : 0));
      }
      while (sum >> 16) sum = (sum & 0xFFFF) + (sum >> 16);
      EXPECT_EQ(sum, 0xFFFFu) << "UDP checksum of datagram " << datagrams << " (" << ip_payload.size() - 8
                              << " bytes), flush " << static_cast<int>(flush);
      EXPECT_NE(ip_payload[6] << 8 | ip_payload[7], 0) << "0 would mean no checksum";
      ++datagrams;
      ip_payload.clear();
    }
    EXPECT_EQ(datagrams, written.size());
  }
}

TEST(PcapWriter, RejectsAPayloadLargerThanADatagram) {
  TempFile file(".pcap");
  PcapWriter writer(file.path());
  UdpDatagram d;
  d.payload.resize(65508);
  EXPECT_THROW(writer.write(d), InputError);
}

TEST(PcapWriter, UnwritablePathIsAnInputError) { EXPECT_THROW(PcapWriter("/nonexistent-dir/x.pcap"), InputError); }

std::string error_of(const std::filesystem::path& path) {
  try {
    read_pcap(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Pcap, MissingFileErrorNamesIt) {
  const std::string error = error_of("/nonexistent/capture.pcap");
  EXPECT_NE(error.find("/nonexistent/capture.pcap"), std::string::npos) << error;
}

TEST(Pcap, NonPcapFileErrorNamesIt) {
  TempFile file(".pcap");
  file.write({'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd', '!', '!',
              '!', '!', '!', '!', '!', '!', '!', '!', '!', '!', '!', '!'});
  const std::string error = error_of(file.path());
  EXPECT_NE(error.find(file.path().string()), std::string::npos) << error;
}

// A capture cut short inside its last record (a recorder killed, a full disk) reads as far as it
// is whole, as libpcap's tools and the Ouster SDK read it, and says where it was cut.
TEST(Pcap, ACaptureCutShortInsideItsLastRecordReadsTheRecordsBeforeIt) {
  const std::filesystem::path sample = kSamples / "OS-1-32-G_v2.1.1_1024x10.pcap";
  PcapStats whole;
  const std::vector<UdpDatagram> all = read_pcap(sample, whole);
  ASSERT_EQ(whole.records, 64u);
  EXPECT_EQ(whole.cut_short_record, 0u);
  std::vector<uint8_t> bytes = test::read_bytes(sample);
  for (const size_t cut : {size_t{100}, size_t{1}}) {  // into the last frame
    std::vector<uint8_t> shorter(bytes.begin(), bytes.end() - static_cast<std::ptrdiff_t>(cut));
    TempFile file(".pcap");
    file.write(shorter);
    PcapStats stats;
    const std::vector<UdpDatagram> read = read_pcap(file.path(), stats);
    EXPECT_EQ(stats.cut_short_record, 64u) << cut;
    EXPECT_EQ(stats.records, 63u) << cut;
    ASSERT_FALSE(read.empty());
    EXPECT_EQ(read.front().payload, all.front().payload);
  }
}

TEST(Pcap, BadIpv4HeaderErrorNamesTheProblem) {
  std::vector<uint8_t> frame = test::ipv4_frame({}, test::udp_bytes(1, 2, {1, 2, 3}));
  frame[14] = 0x65;  // IP version 6 in an IPv4 ethertype frame
  TempFile file(".pcap");
  file.write(test::raw_pcap({RawRecord{1, 0, frame}}));
  EXPECT_NE(error_of(file.path()).find("version"), std::string::npos) << error_of(file.path());
}

TEST(Pcap, BadUdpLengthIsAnInputError) {
  std::vector<uint8_t> udp = test::udp_bytes(1, 2, {1, 2, 3});
  udp[5] = 200;  // UDP length beyond the IP payload
  TempFile file(".pcap");
  file.write(test::raw_pcap({RawRecord{1, 0, test::ipv4_frame({}, udp)}}));
  EXPECT_NE(error_of(file.path()).find("UDP length"), std::string::npos);
}

TEST(Pcap, SkipsNonUdpAndSnaplenTruncatedFrames) {
  std::vector<uint8_t> arp(42, 0);
  arp[12] = 0x08;
  arp[13] = 0x06;
  IpFields tcp;
  tcp.protocol = 6;
  const auto udp_frame = test::ipv4_frame({}, test::udp_bytes(5, 6, {9}));
  std::vector<uint8_t> cut = test::ipv4_frame({}, test::udp_bytes(5, 6, std::vector<uint8_t>(100, 1)));
  const uint32_t full_length = static_cast<uint32_t>(cut.size());
  cut.resize(60);
  TempFile file(".pcap");
  file.write(test::raw_pcap({RawRecord{1, 0, arp}, RawRecord{1, 1, test::ipv4_frame(tcp, {1, 2, 3, 4})},
                             RawRecord{1, 2, cut, full_length}, RawRecord{1, 3, udp_frame}}));
  PcapStats stats;
  const auto datagrams = read_pcap(file.path(), stats);
  ASSERT_EQ(datagrams.size(), 1u);
  EXPECT_EQ(datagrams[0].payload, std::vector<uint8_t>{9});
  EXPECT_EQ(stats.records, 4u);
  EXPECT_EQ(stats.not_udp, 2u);
  EXPECT_EQ(stats.truncated_frames, 1u);
}

TEST(Pcap, IgnoresEthernetPaddingAfterTheIpPacket) {
  std::vector<uint8_t> frame = test::ipv4_frame({}, test::udp_bytes(5, 6, {7}));
  frame.resize(60, 0xEE);  // minimum Ethernet frame
  TempFile file(".pcap");
  file.write(test::raw_pcap({RawRecord{1, 0, frame}}));
  EXPECT_EQ(read_pcap(file.path()).at(0).payload, std::vector<uint8_t>{7});
}

TEST(Pcap, ReadsLinuxCookedAndVlanTaggedFrames) {
  const auto ip_packet = [] {
    auto f = test::ipv4_frame({}, test::udp_bytes(5, 6, {1, 2}));
    return std::vector<uint8_t>(f.begin() + 14, f.end());
  }();
  std::vector<uint8_t> sll(16, 0);
  sll[14] = 0x08;
  sll.insert(sll.end(), ip_packet.begin(), ip_packet.end());
  TempFile sll_file(".pcap");
  sll_file.write(test::raw_pcap({RawRecord{1, 0, sll}}, 113));  // LINKTYPE_LINUX_SLL
  EXPECT_EQ(read_pcap(sll_file.path()).at(0).payload, (std::vector<uint8_t>{1, 2}));

  std::vector<uint8_t> vlan(12, 0x02);
  vlan.insert(vlan.end(), {0x81, 0x00, 0x00, 0x05, 0x08, 0x00});
  vlan.insert(vlan.end(), ip_packet.begin(), ip_packet.end());
  TempFile vlan_file(".pcap");
  vlan_file.write(test::raw_pcap({RawRecord{1, 0, vlan}}));
  EXPECT_EQ(read_pcap(vlan_file.path()).at(0).dst_port, 6);
}

TEST(Pcap, UnsupportedLinkTypeIsAnInputError) {
  TempFile file(".pcap");
  file.write(test::raw_pcap({}, 105));  // IEEE 802.11
  EXPECT_NE(error_of(file.path()).find("link type"), std::string::npos);
}

// Splits one UDP datagram's IP payload into fragments at the given byte offsets.
std::vector<RawRecord> fragments(const std::vector<uint8_t>& ip_payload, const std::vector<uint32_t>& cuts,
                                 uint16_t id = 7) {
  std::vector<RawRecord> out;
  for (size_t i = 0; i < cuts.size(); ++i) {
    const uint32_t begin = cuts[i];
    const uint32_t end = i + 1 < cuts.size() ? cuts[i + 1] : static_cast<uint32_t>(ip_payload.size());
    IpFields ip;
    ip.id = id;
    ip.offset = begin;
    ip.more_fragments = i + 1 < cuts.size();
    out.push_back(
        {1, static_cast<uint32_t>(i), test::ipv4_frame(ip, {ip_payload.begin() + begin, ip_payload.begin() + end})});
  }
  return out;
}

TEST(PcapReassembly, AcceptsFragmentsOutOfOrderAndDuplicated) {
  std::vector<uint8_t> payload(3000);
  for (size_t i = 0; i < payload.size(); ++i) payload[i] = static_cast<uint8_t>(i * 7);
  auto records = fragments(test::udp_bytes(100, 200, payload), {0, 1480, 2960});
  std::swap(records[0], records[2]);
  records.insert(records.begin() + 2, records[1]);  // a duplicated frame
  TempFile file(".pcap");
  file.write(test::raw_pcap(records));
  PcapStats stats;
  const auto datagrams = read_pcap(file.path(), stats);
  ASSERT_EQ(datagrams.size(), 1u);
  EXPECT_EQ(datagrams[0].payload, payload);
  EXPECT_EQ(stats.fragments, 4u);
  EXPECT_EQ(stats.incomplete_datagrams, 0u);
}

TEST(PcapReassembly, DropsAndCountsAnIncompleteSet) {
  auto records = fragments(test::udp_bytes(100, 200, std::vector<uint8_t>(3000, 1)), {0, 1480, 2960});
  records.erase(records.begin() + 1);
  auto whole = test::ipv4_frame({}, test::udp_bytes(1, 2, {42}));
  records.push_back({2, 0, whole});
  TempFile file(".pcap");
  file.write(test::raw_pcap(records));
  PcapStats stats;
  const auto datagrams = read_pcap(file.path(), stats);
  ASSERT_EQ(datagrams.size(), 1u);
  EXPECT_EQ(datagrams[0].payload, std::vector<uint8_t>{42});
  EXPECT_EQ(stats.incomplete_datagrams, 1u);
}

TEST(PcapReassembly, DropsOverlappingFragmentsThatDisagree) {
  const auto udp = test::udp_bytes(100, 200, std::vector<uint8_t>(2000, 1));
  auto records = fragments(udp, {0, 1480});
  std::vector<uint8_t> liar(udp.begin() + 1000, udp.begin() + 1480);
  liar[10] ^= 0xFF;
  IpFields ip;
  ip.offset = 1000;
  ip.more_fragments = true;
  records.insert(records.begin() + 1, RawRecord{1, 5, test::ipv4_frame(ip, liar)});
  TempFile file(".pcap");
  file.write(test::raw_pcap(records));
  PcapStats stats;
  EXPECT_TRUE(read_pcap(file.path(), stats).empty());
  EXPECT_EQ(stats.conflicting_datagrams, 1u);
}

TEST(PcapReassembly, KeepsSetsWithTheSameIdFromDifferentSourcesApart) {
  const auto a = test::udp_bytes(1, 7502, std::vector<uint8_t>(2000, 0xAA));
  const auto b = test::udp_bytes(2, 7502, std::vector<uint8_t>(2000, 0xBB));
  auto ra = fragments(a, {0, 1480});
  auto rb = fragments(b, {0, 1480});
  for (auto& r : rb) r.frame[14 + 15] = 3;  // source 10.0.0.3 instead of 10.0.0.2, same IP id
  TempFile file(".pcap");
  file.write(test::raw_pcap({ra[0], rb[0], rb[1], ra[1]}));
  const auto datagrams = read_pcap(file.path());
  ASSERT_EQ(datagrams.size(), 2u);
  EXPECT_EQ(datagrams[0].src_port, 2);
  EXPECT_EQ(datagrams[1].src_port, 1);
  EXPECT_EQ(datagrams[1].payload, std::vector<uint8_t>(2000, 0xAA));
}

}  // namespace
}  // namespace lidartwin
