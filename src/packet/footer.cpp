// Packet footers (protocol doc 4.5).
#include "packet/footer.h"

#include <cassert>
#include <cstring>

#include "packet/field_table.h"

namespace lidartwin::packet_detail {

void write_footer(std::span<uint8_t> packet, FooterKind footer) {
  assert(packet.size() >= static_cast<size_t>(kCrcBytes));
  const auto body = packet.first(packet.size() - kCrcBytes);
  uint64_t word = 0;
  if (footer == FooterKind::kCrc64) word = crc64_xz(body);
  if (footer == FooterKind::kFw2Marker) word = kFw2FooterMarker;
  std::memcpy(packet.data() + body.size(), &word, sizeof word);
}

// A CRC equal to the marker or to zero has odds of 2^-64, so those are tested first and the CRC
// is computed only for the remaining packets.
std::pair<FooterKind, bool> classify_footer(std::span<const uint8_t> packet) {
  assert(packet.size() >= static_cast<size_t>(kCrcBytes));
  const auto body = packet.first(packet.size() - kCrcBytes);
  uint64_t word = 0;
  std::memcpy(&word, packet.data() + body.size(), sizeof word);
  if (word == kFw2FooterMarker) return {FooterKind::kFw2Marker, true};
  if (word == 0) return {FooterKind::kZero, true};
  if (word == crc64_xz(body)) return {FooterKind::kCrc64, true};
  return {FooterKind::kOther, false};
}

}  // namespace lidartwin::packet_detail
