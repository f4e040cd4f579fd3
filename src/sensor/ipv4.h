#pragma once
// Strict dotted-quad IPv4 parsing for udp_dest (the streamer sends IPv4 only).
#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

namespace lidartwin {

// "a.b.c.d" with four decimal octets; nothing else (no "1.2.3", no host names, no IPv6).
std::optional<std::array<uint8_t, 4>> parse_ipv4(std::string_view text);

}  // namespace lidartwin
