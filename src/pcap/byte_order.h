#pragma once
// Network (big-endian) byte order for the Ethernet, IP and UDP headers. Callers check bounds first;
// these only read or write the bytes they are given.
#include <cstddef>
#include <cstdint>
#include <span>

namespace lidartwin::pcap_detail {

inline uint16_t load_be16(std::span<const uint8_t> bytes, size_t offset) {
  return static_cast<uint16_t>((bytes[offset] << 8) | bytes[offset + 1]);
}

inline void store_be16(std::span<uint8_t> bytes, size_t offset, uint16_t value) {
  bytes[offset] = static_cast<uint8_t>(value >> 8);
  bytes[offset + 1] = static_cast<uint8_t>(value & 0xFF);
}

}  // namespace lidartwin::pcap_detail
