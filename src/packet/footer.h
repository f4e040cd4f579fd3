#pragma once
// The last 8 bytes of a non-legacy lidar or IMU packet (protocol doc 4.5), shared by both.
#include <cstdint>
#include <span>
#include <utility>

#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin::packet_detail {

// Fills the last 8 bytes of packet according to footer; the CRC covers everything before them.
void write_footer(std::span<uint8_t> packet, FooterKind footer);
// The kind of the last 8 bytes and whether they are consistent (false only for kOther).
std::pair<FooterKind, bool> classify_footer(std::span<const uint8_t> packet);

}  // namespace lidartwin::packet_detail
