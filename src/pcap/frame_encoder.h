#pragma once
// A UDP datagram -> the Ethernet/IPv4 frames a sender puts on the wire (fragmented at the MTU).
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lidartwin/pcap/pcap.h"

namespace lidartwin::pcap_detail {

inline constexpr size_t kEthernetMtu = 1500;
inline constexpr size_t kMaxUdpPayload = 65535 - 20 - 8;

// RFC 1071 ones'-complement sum, folded and inverted. A header holding its own correct checksum
// sums to 0.
uint16_t internet_checksum(std::span<const uint8_t> bytes, uint32_t initial_sum = 0);

// Of a datagram's Ethernet frames, the headers (Ethernet, IPv4 and, in the first, UDP) and where
// the rest of the frame lies in the datagram's payload: a writer sends the header bytes and the
// payload slice as they are, so the payload is never copied in user space.
struct FrameParts {
  static constexpr size_t kMaxHeader = 14 + 20 + 8;
  std::array<uint8_t, kMaxHeader> header{};
  size_t header_size = 0;
  size_t payload_offset = 0;  // into datagram.payload
  size_t payload_size = 0;
  size_t size() const { return header_size + payload_size; }
};

// The frames of one datagram, in offset order as Linux sends them, into `out` (reused between
// calls). Requires payload <= kMaxUdpPayload.
void split_frames(const UdpDatagramView& datagram, uint16_t ip_id, std::vector<FrameParts>& out,
                  size_t mtu = kEthernetMtu);

}  // namespace lidartwin::pcap_detail
