// Reading captures with libpcap: frames -> IPv4 (reassembled) -> UDP datagrams.
#include <string>
#include <string_view>
#include <utility>

#include <pcap/pcap.h>

#include "lidartwin/error.h"
#include "lidartwin/pcap/pcap.h"
#include "pcap/byte_order.h"
#include "pcap/frame_decoder.h"
#include "pcap/ipv4_reassembler.h"

namespace lidartwin {
namespace {

constexpr uint8_t kProtocolUdp = 17;
constexpr size_t kUdpHeader = 8;

// The reader opens files at nanosecond precision, so tv_usec holds nanoseconds.
uint64_t timestamp_ns(const pcap_pkthdr& header) {
  return static_cast<uint64_t>(header.ts.tv_sec) * 1'000'000'000ULL + static_cast<uint64_t>(header.ts.tv_usec);
}

}  // namespace

struct PcapReader::Impl {
  std::string name;
  pcap_t* handle = nullptr;
  int link_type = 0;
  PcapStats stats;
  pcap_detail::Ipv4Reassembler reassembler;
  bool finished = false;
  size_t record_number = 0;  // 1-based, of the record being read

  ~Impl() {
    if (handle) pcap_close(handle);
  }

  [[noreturn]] void fail(const std::string& problem) const {
    throw InputError(name + ": record " + std::to_string(record_number) + ": " + problem);
  }

  std::optional<UdpDatagram> from_frame(const pcap_pkthdr& header, const uint8_t* bytes);
  UdpDatagram to_datagram(const pcap_detail::Ipv4Fragment& ip, std::span<const uint8_t> udp,
                          const pcap_pkthdr& header) const;
};

PcapReader::PcapReader(const std::filesystem::path& path) : impl_(std::make_unique<Impl>()) {
  impl_->name = path.string();
  char error[PCAP_ERRBUF_SIZE] = {};
  // Nanosecond precision: libpcap scales microsecond files up, and keeps nanosecond files exact.
  impl_->handle = pcap_open_offline_with_tstamp_precision(path.c_str(), PCAP_TSTAMP_PRECISION_NANO, error);
  if (!impl_->handle) throw InputError(impl_->name + ": cannot read capture: " + error);
  impl_->link_type = pcap_datalink(impl_->handle);
  if (!pcap_detail::link_type_supported(impl_->link_type)) {
    throw InputError(impl_->name + ": unsupported link type " + std::to_string(impl_->link_type) +
                     " (expected Ethernet, Linux cooked or raw IP)");
  }
}

PcapReader::~PcapReader() = default;

const PcapStats& PcapReader::stats() const { return impl_->stats; }

std::optional<UdpDatagram> PcapReader::next() {
  Impl& impl = *impl_;
  while (!impl.finished) {
    pcap_pkthdr* header = nullptr;
    const u_char* bytes = nullptr;
    impl.record_number = impl.stats.records + 1;
    const int status = pcap_next_ex(impl.handle, &header, &bytes);
    // A file cut short inside its last record (libpcap: "truncated dump file; tried to read ...")
    // ends there: what came before is whole, and a recording interrupted by a full disk or a kill
    // stays readable.
    const bool cut_short =
        status == PCAP_ERROR && std::string_view(pcap_geterr(impl.handle)).starts_with("truncated dump file");
    if (cut_short) impl.stats.cut_short_record = impl.record_number;
    if (status == PCAP_ERROR_BREAK || cut_short) {  // end of file
      impl.reassembler.finish();
      impl.stats.incomplete_datagrams = impl.reassembler.incomplete();
      impl.stats.conflicting_datagrams = impl.reassembler.conflicting();
      impl.finished = true;
      break;
    }
    if (status != 1) impl.fail(std::string("unreadable: ") + pcap_geterr(impl.handle));
    ++impl.stats.records;
    if (std::optional<UdpDatagram> datagram = impl.from_frame(*header, bytes)) {
      ++impl.stats.datagrams;
      return datagram;
    }
  }
  return std::nullopt;
}

// One frame -> a datagram, or nothing yet (skipped frame, or a fragment of an unfinished set).
std::optional<UdpDatagram> PcapReader::Impl::from_frame(const pcap_pkthdr& header, const uint8_t* bytes) {
  if (header.caplen < header.len) {
    ++stats.truncated_frames;
    return std::nullopt;
  }
  const pcap_detail::DecodedFrame frame = pcap_detail::decode_frame(link_type, {bytes, header.caplen});
  if (frame.kind == pcap_detail::DecodedFrame::Kind::kMalformed) fail(frame.error);
  const pcap_detail::Ipv4Fragment& ip = frame.packet;
  if (frame.kind == pcap_detail::DecodedFrame::Kind::kNotIpv4 || ip.protocol != kProtocolUdp) {
    ++stats.not_udp;
    return std::nullopt;
  }
  if (!ip.is_fragment()) return to_datagram(ip, ip.payload, header);
  ++stats.fragments;
  std::optional<std::vector<uint8_t>> whole = reassembler.add(ip, timestamp_ns(header));
  stats.incomplete_datagrams = reassembler.incomplete();
  stats.conflicting_datagrams = reassembler.conflicting();
  if (!whole) return std::nullopt;
  return to_datagram(ip, *whole, header);
}

// RFC 768 header; the UDP length bounds the payload. The checksum is not checked: captures taken
// on the sending host hold checksums the NIC had not yet filled in.
UdpDatagram PcapReader::Impl::to_datagram(const pcap_detail::Ipv4Fragment& ip, std::span<const uint8_t> udp,
                                          const pcap_pkthdr& header) const {
  if (udp.size() < kUdpHeader) fail("UDP header needs 8 bytes, the IP payload has " + std::to_string(udp.size()));
  const size_t length = pcap_detail::load_be16(udp, 4);
  if (length < kUdpHeader || length > udp.size()) {
    fail("UDP length " + std::to_string(length) + " does not fit the " + std::to_string(udp.size()) +
         "-byte IP payload");
  }
  UdpDatagram datagram;
  datagram.timestamp_ns = timestamp_ns(header);
  datagram.src_ip = ip.src;
  datagram.dst_ip = ip.dst;
  datagram.src_port = pcap_detail::load_be16(udp, 0);
  datagram.dst_port = pcap_detail::load_be16(udp, 2);
  datagram.payload.assign(udp.begin() + kUdpHeader, udp.begin() + static_cast<std::ptrdiff_t>(length));
  return datagram;
}

std::vector<UdpDatagram> read_pcap(const std::filesystem::path& path, PcapStats& stats) {
  PcapReader reader(path);
  std::vector<UdpDatagram> datagrams;
  while (std::optional<UdpDatagram> datagram = reader.next()) datagrams.push_back(std::move(*datagram));
  stats = reader.stats();
  return datagrams;
}

std::vector<UdpDatagram> read_pcap(const std::filesystem::path& path) {
  PcapStats stats;
  return read_pcap(path, stats);
}

}  // namespace lidartwin
