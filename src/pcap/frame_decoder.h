#pragma once
// One captured link-layer frame -> the IPv4 packet inside it (header fields and payload view).
#include <array>
#include <cstdint>
#include <span>
#include <string>

namespace lidartwin::pcap_detail {

struct Ipv4Fragment {
  std::array<uint8_t, 4> src{};
  std::array<uint8_t, 4> dst{};
  uint16_t id = 0;
  uint8_t protocol = 0;
  uint32_t offset = 0;  // bytes into the original IP payload
  bool more_fragments = false;
  std::span<const uint8_t> payload;  // this fragment's share of the IP payload, padding removed
  bool is_fragment() const { return more_fragments || offset != 0; }
};

struct DecodedFrame {
  enum class Kind { kIpv4, kNotIpv4, kMalformed } kind = Kind::kNotIpv4;
  Ipv4Fragment packet;  // valid when kind == kIpv4
  std::string error;    // says what is wrong when kind == kMalformed
};

// Whether decode_frame understands a pcap link type (DLT_* value).
bool link_type_supported(int link_type);

// Splits off the link-layer header (Ethernet with up to two VLAN tags, Linux SLL/SLL2, raw IP)
// and checks the IPv4 header against the bytes actually present.
DecodedFrame decode_frame(int link_type, std::span<const uint8_t> frame);

}  // namespace lidartwin::pcap_detail
