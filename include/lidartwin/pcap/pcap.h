#pragma once
// Classic libpcap captures of Ethernet/IPv4/UDP, as real Ouster captures are (protocol doc 9).
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace lidartwin {

struct UdpDatagram {
  uint64_t timestamp_ns = 0;  // capture time
  std::array<uint8_t, 4> src_ip{127, 0, 0, 1};
  std::array<uint8_t, 4> dst_ip{127, 0, 0, 1};
  uint16_t src_port = 0;
  uint16_t dst_port = 0;
  std::vector<uint8_t> payload;  // reassembled from IPv4 fragments
  friend bool operator==(const UdpDatagram&, const UdpDatagram&) = default;
};

// The same datagram with its payload borrowed: what writers take, so a packet already encoded in a
// frame buffer goes to the capture without a copy.
struct UdpDatagramView {
  uint64_t timestamp_ns = 0;
  std::array<uint8_t, 4> src_ip{127, 0, 0, 1};
  std::array<uint8_t, 4> dst_ip{127, 0, 0, 1};
  uint16_t src_port = 0;
  uint16_t dst_port = 0;
  std::span<const uint8_t> payload;
};
inline UdpDatagramView view_of(const UdpDatagram& d) {
  return {d.timestamp_ns, d.src_ip, d.dst_ip, d.src_port, d.dst_port, d.payload};
}

// What a read saw besides the datagrams it returned.
struct PcapStats {
  size_t records = 0;                // capture records (link-layer frames) read
  size_t datagrams = 0;              // UDP datagrams returned
  size_t fragments = 0;              // records that carried an IPv4 fragment
  size_t not_udp = 0;                // frames skipped: not IPv4 (ARP, IPv6…), or IPv4 but not UDP
  size_t truncated_frames = 0;       // frames cut short by the capture's snaplen, skipped
  size_t incomplete_datagrams = 0;   // fragment sets that never completed, dropped
  size_t conflicting_datagrams = 0;  // fragment sets with overlapping, disagreeing bytes, dropped
  // The file ends inside its last record (a capture cut short: a full disk, a recorder killed):
  // that record's number (1-based); the records before it were read. 0: the file ends whole.
  size_t cut_short_record = 0;
  friend bool operator==(const PcapStats&, const PcapStats&) = default;
};

// Reads a capture one UDP datagram at a time, reassembling IPv4 fragments, so a capture larger
// than memory can be processed. Link types: Ethernet (with 802.1Q tags), Linux cooked (SLL and
// SLL2) and raw IP. A file that ends inside its last record ends there, as libpcap's readers and
// the Ouster SDK's end (PcapStats::cut_short_record says so). Throws InputError naming the file and
// the problem (not a pcap, bad record length, bad IP or UDP header, unsupported link type); never
// crashes on hostile input.
class PcapReader {
 public:
  explicit PcapReader(const std::filesystem::path& path);
  ~PcapReader();
  PcapReader(const PcapReader&) = delete;
  PcapReader& operator=(const PcapReader&) = delete;
  // The next datagram in order of completion, or nullopt at the end of the capture.
  std::optional<UdpDatagram> next();
  const PcapStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Reads every UDP datagram, reassembling IPv4 fragments. Throws InputError naming the file and
// the problem (not a pcap, truncated record, bad IP header…); never crashes on hostile input.
std::vector<UdpDatagram> read_pcap(const std::filesystem::path& path);
std::vector<UdpDatagram> read_pcap(const std::filesystem::path& path, PcapStats& stats);

// When written datagrams reach the file.
enum class PcapFlush {
  kEachDatagram,  // in the file when write() returns: a reader may follow a live capture (serve --record)
  kInBlocks,      // in 4 MiB blocks that a background thread writes with O_DIRECT where the file
                  // system takes it (no page-cache copy on the caller's thread: `record`); close()
                  // writes the rest
};

// Writes datagrams as a real capture has them: Ethernet + IPv4 + UDP, fragmented at a 1500-byte MTU.
// Timestamps are stored in microseconds (classic pcap), so sub-microsecond parts are dropped.
class PcapWriter {
 public:
  // Throws InputError if it cannot create the file.
  explicit PcapWriter(const std::filesystem::path& path, PcapFlush flush = PcapFlush::kEachDatagram);
  ~PcapWriter();  // closes; a write error is reported only by close()
  PcapWriter(const PcapWriter&) = delete;
  PcapWriter& operator=(const PcapWriter&) = delete;
  // Throws InputError if the payload does not fit one UDP datagram (65507 bytes), or naming the
  // file if a write failed (disk full): with kInBlocks, a block written earlier, or at close().
  void write(const UdpDatagramView& datagram);
  void write(const UdpDatagram& datagram) { write(view_of(datagram)); }
  // Writes what is staged and closes the file; throws InputError as write() does.
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
