#pragma once
// Hand-built capture files for pcap tests: written byte by byte here, independently of libpcap and
// of the PcapWriter under test, so hostile or unusual captures can be made on purpose.
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

namespace lidartwin::test {

struct RawRecord {
  uint32_t seconds = 0;
  uint32_t microseconds = 0;
  std::vector<uint8_t> frame;
  uint32_t original_length = 0;  // 0: same as frame.size()
};

inline void put_le32(std::vector<uint8_t>& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
inline void put_be16(std::vector<uint8_t>& out, uint16_t v) {
  out.push_back(static_cast<uint8_t>(v >> 8));
  out.push_back(static_cast<uint8_t>(v & 0xFF));
}

// Classic little-endian pcap (magic d4 c3 b2 a1 on disk, as the Ouster samples).
inline std::vector<uint8_t> raw_pcap(const std::vector<RawRecord>& records, uint32_t link_type = 1) {
  std::vector<uint8_t> out;
  put_le32(out, 0xA1B2C3D4);
  out.insert(out.end(), {2, 0, 4, 0});  // version 2.4
  put_le32(out, 0);                     // thiszone
  put_le32(out, 0);                     // sigfigs
  put_le32(out, 262144);                // snaplen
  put_le32(out, link_type);
  for (const RawRecord& r : records) {
    put_le32(out, r.seconds);
    put_le32(out, r.microseconds);
    put_le32(out, static_cast<uint32_t>(r.frame.size()));
    put_le32(out, r.original_length ? r.original_length : static_cast<uint32_t>(r.frame.size()));
    out.insert(out.end(), r.frame.begin(), r.frame.end());
  }
  return out;
}

struct IpFields {
  std::array<uint8_t, 4> src{10, 0, 0, 2};
  std::array<uint8_t, 4> dst{10, 0, 0, 1};
  uint16_t id = 7;
  uint8_t protocol = 17;
  uint32_t offset = 0;  // bytes, multiple of 8
  bool more_fragments = false;
};

// Ethernet + IPv4 header (checksum left 0: readers need not check it) + the given IP payload.
inline std::vector<uint8_t> ipv4_frame(const IpFields& ip, const std::vector<uint8_t>& ip_payload) {
  std::vector<uint8_t> f(12, 0x02);
  put_be16(f, 0x0800);
  f.push_back(0x45);
  f.push_back(0);
  put_be16(f, static_cast<uint16_t>(20 + ip_payload.size()));
  put_be16(f, ip.id);
  put_be16(f, static_cast<uint16_t>((ip.more_fragments ? 0x2000 : 0) | (ip.offset / 8)));
  f.push_back(64);
  f.push_back(ip.protocol);
  put_be16(f, 0);
  f.insert(f.end(), ip.src.begin(), ip.src.end());
  f.insert(f.end(), ip.dst.begin(), ip.dst.end());
  f.insert(f.end(), ip_payload.begin(), ip_payload.end());
  return f;
}

// UDP header + payload (checksum 0 = none), i.e. a whole IP payload before fragmentation.
inline std::vector<uint8_t> udp_bytes(uint16_t src_port, uint16_t dst_port, const std::vector<uint8_t>& payload) {
  std::vector<uint8_t> u;
  put_be16(u, src_port);
  put_be16(u, dst_port);
  put_be16(u, static_cast<uint16_t>(8 + payload.size()));
  put_be16(u, 0);
  u.insert(u.end(), payload.begin(), payload.end());
  return u;
}

// A file path unique to the running test, removed when the object goes out of scope.
class TempFile {
 public:
  explicit TempFile(const std::string& suffix) {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    std::string name = "lidartwin_" + std::to_string(getpid()) + "_" + info->test_suite_name() + "_" + info->name() +
                       "_" + std::to_string(counter()++) + suffix;
    for (char& c : name) c = (c == '/') ? '_' : c;  // parameterized test names hold '/'
    path_ = std::filesystem::temp_directory_path() / name;
  }
  ~TempFile() {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  const std::filesystem::path& path() const { return path_; }
  void write(const std::vector<uint8_t>& bytes) const {
    std::ofstream out(path_, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }

 private:
  static int& counter() {
    static int n = 0;
    return n;
  }
  std::filesystem::path path_;
};

inline std::vector<uint8_t> read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace lidartwin::test
