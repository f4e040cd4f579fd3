#include "pcap/frame_decoder.h"

#include <optional>
#include <string>
#include <utility>

#include <pcap/pcap.h>

#include "pcap/byte_order.h"

namespace lidartwin::pcap_detail {
namespace {

constexpr uint16_t kEtherTypeIpv4 = 0x0800;
constexpr uint16_t kEtherTypeVlan = 0x8100;
constexpr uint16_t kEtherTypeQinQ = 0x88A8;
constexpr size_t kEthernetHeader = 14;
constexpr size_t kSllHeader = 16;   // protocol at byte 14
constexpr size_t kSll2Header = 20;  // protocol at byte 0
constexpr size_t kIpv4MinHeader = 20;

struct Network {
  uint16_t ether_type = 0;
  std::span<const uint8_t> bytes;
};

// Ethernet II, skipping 802.1Q / 802.1ad tags (a capture on a VLAN port carries them).
std::optional<Network> strip_ethernet(std::span<const uint8_t> frame) {
  if (frame.size() < kEthernetHeader) return std::nullopt;
  size_t offset = 12;
  uint16_t type = load_be16(frame, offset);
  for (int tags = 0; tags < 2 && (type == kEtherTypeVlan || type == kEtherTypeQinQ); ++tags) {
    offset += 4;
    if (frame.size() < offset + 2) return std::nullopt;
    type = load_be16(frame, offset);
  }
  return Network{type, frame.subspan(offset + 2)};
}

std::optional<Network> strip_link_layer(int link_type, std::span<const uint8_t> frame) {
  switch (link_type) {
    case DLT_EN10MB: return strip_ethernet(frame);
    case DLT_LINUX_SLL:
      if (frame.size() < kSllHeader) return std::nullopt;
      return Network{load_be16(frame, 14), frame.subspan(kSllHeader)};
    case DLT_LINUX_SLL2:
      if (frame.size() < kSll2Header) return std::nullopt;
      return Network{load_be16(frame, 0), frame.subspan(kSll2Header)};
    case DLT_RAW:
      if (frame.empty() || (frame[0] >> 4) != 4) return Network{0, frame};
      return Network{kEtherTypeIpv4, frame};
    default: return std::nullopt;
  }
}

DecodedFrame malformed(std::string error) {
  DecodedFrame result;
  result.kind = DecodedFrame::Kind::kMalformed;
  result.error = std::move(error);
  return result;
}

// RFC 791 header. The total length is what bounds the payload: Ethernet pads short frames.
DecodedFrame decode_ipv4(std::span<const uint8_t> ip) {
  if (ip.size() < kIpv4MinHeader)
    return malformed("IPv4 header needs 20 bytes, the frame has " + std::to_string(ip.size()));
  if ((ip[0] >> 4) != 4) return malformed("IPv4 version field is " + std::to_string(ip[0] >> 4));
  const size_t header = static_cast<size_t>(ip[0] & 0x0F) * 4;
  const size_t total = load_be16(ip, 2);
  if (header < kIpv4MinHeader) return malformed("IPv4 header length " + std::to_string(header) + " < 20");
  if (total < header || total > ip.size())
    return malformed("IPv4 total length " + std::to_string(total) + " does not fit the header (" +
                     std::to_string(header) + " bytes) and the " + std::to_string(ip.size()) + " bytes present");
  DecodedFrame result;
  result.kind = DecodedFrame::Kind::kIpv4;
  Ipv4Fragment& packet = result.packet;
  const uint16_t flags_offset = load_be16(ip, 6);
  packet.id = load_be16(ip, 4);
  packet.more_fragments = (flags_offset & 0x2000) != 0;
  packet.offset = static_cast<uint32_t>(flags_offset & 0x1FFF) * 8;
  packet.protocol = ip[9];
  for (size_t i = 0; i < 4; ++i) {
    packet.src[i] = ip[12 + i];
    packet.dst[i] = ip[16 + i];
  }
  packet.payload = ip.subspan(header, total - header);
  return result;
}

}  // namespace

bool link_type_supported(int link_type) {
  return link_type == DLT_EN10MB || link_type == DLT_LINUX_SLL || link_type == DLT_LINUX_SLL2 || link_type == DLT_RAW;
}

DecodedFrame decode_frame(int link_type, std::span<const uint8_t> frame) {
  const std::optional<Network> network = strip_link_layer(link_type, frame);
  if (!network) {
    return malformed("link-layer header needs more than the " + std::to_string(frame.size()) + " bytes of the frame");
  }
  if (network->ether_type != kEtherTypeIpv4) return DecodedFrame{};
  return decode_ipv4(network->bytes);
}

}  // namespace lidartwin::pcap_detail
