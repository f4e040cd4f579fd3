#pragma once
// A UDP datagram -> the Ethernet/IPv4 frames a sender puts on the wire (fragmented at the MTU).
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "lidartwin/pcap/pcap.h"

namespace lidartwin::pcap_detail {

inline constexpr size_t kEthernetMtu = 1500;
inline constexpr size_t kMaxUdpPayload = 65535 - 20 - 8;

// RFC 1071 ones'-complement sum, folded and inverted. A header holding its own correct checksum
// sums to 0.
uint16_t internet_checksum(std::span<const uint8_t> bytes, uint32_t initial_sum = 0);

// Buffers reused between calls, so a recorder writes without allocating per packet.
struct FrameScratch {
  std::vector<uint8_t> frame;
};

// Calls emit once per frame, in offset order as Linux sends them. Requires
// payload <= kMaxUdpPayload.
void encode_frames(const UdpDatagramView& datagram, uint16_t ip_id, FrameScratch& scratch,
                   const std::function<void(std::span<const uint8_t>)>& emit, size_t mtu = kEthernetMtu);

}  // namespace lidartwin::pcap_detail
