#include "pcap/frame_encoder.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cstring>

#include "pcap/byte_order.h"

namespace lidartwin::pcap_detail {
namespace {

constexpr size_t kEthernetHeader = 14;
constexpr size_t kIpv4Header = 20;
constexpr size_t kUdpHeader = 8;
constexpr uint8_t kTtl = 64;
constexpr uint8_t kProtocolUdp = 17;

// The ones'-complement sum of the big-endian 16-bit words of bytes, added to sum (not folded).
// RFC 1071 2(B): the sum can be taken in the machine's byte order and swapped at the end, so eight
// bytes are added at a time (the checksum runs over every byte `record` writes; byte pairs ran at
// about 1 GB/s), into four sums that do not wait for each other (one ran at an add's latency per
// word). Adding 32-bit halves into 64 bits cannot overflow for a datagram (< 2^17 adds).
uint32_t add_words(std::span<const uint8_t> bytes, uint32_t sum) {
  const uint8_t* p = bytes.data();
  const size_t n = bytes.size();
  size_t i = 0;
  uint64_t lanes[4] = {};
  for (; i + 32 <= n; i += 32) {
    for (size_t k = 0; k < 4; ++k) {
      uint64_t word;
      std::memcpy(&word, p + i + 8 * k, 8);
      lanes[k] += (word & 0xFFFF'FFFFu) + (word >> 32);
    }
  }
  uint64_t wide = lanes[0] + lanes[1] + lanes[2] + lanes[3];
  for (; i + 8 <= n; i += 8) {
    uint64_t word;
    std::memcpy(&word, p + i, 8);
    wide += (word & 0xFFFF'FFFFu) + (word >> 32);
  }
  while (wide >> 16) wide = (wide & 0xFFFF) + (wide >> 16);
  const auto native = static_cast<uint32_t>(wide);
  sum += std::endian::native == std::endian::little ? ((native & 0xFF) << 8) | (native >> 8) : native;
  for (; i + 1 < n; i += 2) sum += load_be16(bytes, i);
  if (i < n) sum += static_cast<uint32_t>(bytes[i]) << 8;
  return sum;
}

// Locally administered MACs derived from the IPs, so a capture shows one stable address per host.
void write_ethernet(std::span<uint8_t> frame, const UdpDatagramView& datagram) {
  const uint8_t dst[6] = {0x02, 0x00, datagram.dst_ip[0], datagram.dst_ip[1], datagram.dst_ip[2], datagram.dst_ip[3]};
  const uint8_t src[6] = {0x02, 0x00, datagram.src_ip[0], datagram.src_ip[1], datagram.src_ip[2], datagram.src_ip[3]};
  std::copy(dst, dst + 6, frame.begin());
  std::copy(src, src + 6, frame.begin() + 6);
  store_be16(frame, 12, 0x0800);
}

void write_ipv4(std::span<uint8_t> ip, const UdpDatagramView& datagram, uint16_t id, size_t offset, size_t length,
                bool more_fragments) {
  ip[0] = 0x45;  // version 4, 5-word header
  ip[1] = 0;
  store_be16(ip, 2, static_cast<uint16_t>(kIpv4Header + length));
  store_be16(ip, 4, id);
  store_be16(ip, 6, static_cast<uint16_t>((more_fragments ? 0x2000 : 0) | (offset / 8)));
  ip[8] = kTtl;
  ip[9] = kProtocolUdp;
  store_be16(ip, 10, 0);
  std::copy(datagram.src_ip.begin(), datagram.src_ip.end(), ip.begin() + 12);
  std::copy(datagram.dst_ip.begin(), datagram.dst_ip.end(), ip.begin() + 16);
  store_be16(ip, 10, internet_checksum(ip.first(kIpv4Header)));
}

// The 8-byte UDP header of the datagram. The checksum covers the RFC 768 pseudo-header, this
// header and the payload; 0 would mean "no checksum", so a computed 0 is sent as 0xFFFF.
std::array<uint8_t, kUdpHeader> udp_header(const UdpDatagramView& datagram) {
  std::array<uint8_t, kUdpHeader> header{};
  const size_t length = kUdpHeader + datagram.payload.size();
  store_be16(header, 0, datagram.src_port);
  store_be16(header, 2, datagram.dst_port);
  store_be16(header, 4, static_cast<uint16_t>(length));
  uint32_t sum = add_words(datagram.src_ip, 0);
  sum = add_words(datagram.dst_ip, sum) + kProtocolUdp + static_cast<uint32_t>(length);
  sum = add_words(header, sum);  // an even number of bytes: the payload's words stay aligned
  const uint16_t checksum = internet_checksum(datagram.payload, sum);
  store_be16(header, 6, checksum == 0 ? 0xFFFF : checksum);
  return header;
}

}  // namespace

uint16_t internet_checksum(std::span<const uint8_t> bytes, uint32_t initial_sum) {
  uint32_t sum = add_words(bytes, initial_sum);
  while (sum >> 16) sum = (sum & 0xFFFF) + (sum >> 16);
  return static_cast<uint16_t>(~sum & 0xFFFF);
}

void split_frames(const UdpDatagramView& datagram, uint16_t ip_id, std::vector<FrameParts>& out, size_t mtu) {
  assert(datagram.payload.size() <= kMaxUdpPayload);
  const std::array<uint8_t, kUdpHeader> header = udp_header(datagram);
  const size_t udp_size = kUdpHeader + datagram.payload.size();
  // The IP payload is the UDP header then the datagram's payload. Every fragment but the last
  // carries a multiple of 8 bytes (RFC 791): 1480 at a 1500 MTU.
  const size_t per_fragment = (mtu - kIpv4Header) / 8 * 8;
  out.clear();
  for (size_t offset = 0; offset < udp_size; offset += per_fragment) {
    const size_t length = std::min(per_fragment, udp_size - offset);
    const bool more = offset + length < udp_size;
    FrameParts& frame = out.emplace_back();
    const std::span<uint8_t> bytes(frame.header);
    write_ethernet(bytes, datagram);
    write_ipv4(bytes.subspan(kEthernetHeader), datagram, ip_id, offset, length, more);
    frame.header_size = kEthernetHeader + kIpv4Header;
    size_t from = offset;  // offset into the UDP header + payload
    if (from < kUdpHeader) {
      const size_t n = std::min(kUdpHeader - from, length);
      std::memcpy(frame.header.data() + frame.header_size, header.data() + from, n);
      frame.header_size += n;
      from += n;
    }
    frame.payload_offset = from - kUdpHeader;
    frame.payload_size = offset + length - from;
  }
}

}  // namespace lidartwin::pcap_detail
