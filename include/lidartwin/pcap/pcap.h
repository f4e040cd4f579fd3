#pragma once
// Classic libpcap captures of Ethernet/IPv4/UDP, as real Ouster captures are (protocol doc 9).
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

namespace lidartwin {

struct UdpDatagram {
  uint64_t timestamp_ns = 0;  // capture time
  std::array<uint8_t, 4> src_ip{127, 0, 0, 1};
  std::array<uint8_t, 4> dst_ip{127, 0, 0, 1};
  uint16_t src_port = 0;
  uint16_t dst_port = 0;
  std::vector<uint8_t> payload;  // reassembled from IPv4 fragments
};

// Reads every UDP datagram, reassembling IPv4 fragments. Throws InputError naming the file and
// the problem (not a pcap, truncated record, bad IP header…); never crashes on hostile input.
std::vector<UdpDatagram> read_pcap(const std::filesystem::path& path);

// Writes datagrams as a real capture has them: Ethernet + IPv4 + UDP, fragmented at a 1500-byte MTU.
class PcapWriter {
 public:
  explicit PcapWriter(const std::filesystem::path& path);  // throws InputError if it cannot open
  ~PcapWriter();
  PcapWriter(const PcapWriter&) = delete;
  PcapWriter& operator=(const PcapWriter&) = delete;
  void write(const UdpDatagram& datagram);
  void flush();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
