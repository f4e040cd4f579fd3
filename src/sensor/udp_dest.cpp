// udp_dest resolution at write time (protocol doc 1.6, 2.7) and strict IPv4 parsing.
#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <memory>

#include "lidartwin/sensor/config_rules.h"
#include "sensor/ipv4.h"

namespace lidartwin {
namespace {

bool starts_with_nocase(std::string_view text, std::string_view prefix) {
  return text.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), text.begin(), [](char a, char b) {
           return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
         });
}

// "@auto": the address the HTTP request came from. IPv6 loopback and IPv4-mapped peers map to
// IPv4 because the streamer sends IPv4 only (the SDK's sockets are dual-stack and receive it).
std::string peer_ipv4(const std::string& peer_ip, const json_reader::Location& at) {
  if (peer_ip.empty()) {
    at.fail("\"@auto\" means the address of the HTTP client, and there is none here; give an IPv4 address");
  }
  if (parse_ipv4(peer_ip)) return peer_ip;
  if (starts_with_nocase(peer_ip, "::ffff:") && parse_ipv4(peer_ip.substr(7))) {
    return peer_ip.substr(7);
  }
  if (peer_ip == "::1") return "127.0.0.1";
  at.fail("\"@auto\" resolved to the IPv6 client address " + peer_ip +
          ", but lidartwin streams over IPv4 only; give an IPv4 address");
}

std::string resolve_host_name(const std::string& name, const json_reader::Location& at) {
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const int rc = ::getaddrinfo(name.c_str(), nullptr, &hints, &found);
  const std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> owner(found, &::freeaddrinfo);
  char host[NI_MAXHOST] = {};
  if (rc != 0 || found == nullptr ||
      ::getnameinfo(found->ai_addr, found->ai_addrlen, host, sizeof host, nullptr, 0, NI_NUMERICHOST) != 0) {
    at.fail("cannot resolve host name \"" + name + "\" to an IPv4 address" +
            (rc != 0 ? std::string(" (") + ::gai_strerror(rc) + ")" : ""));
  }
  return host;
}

bool looks_numeric(const std::string& text) {
  return std::all_of(text.begin(), text.end(),
                     [](char c) { return c == '.' || std::isdigit(static_cast<unsigned char>(c)); });
}

}  // namespace

std::optional<std::array<uint8_t, 4>> parse_ipv4(std::string_view text) {
  std::array<uint8_t, 4> octets{};
  in_addr address{};
  const std::string copy(text);
  // inet_pton(AF_INET) accepts exactly four decimal octets (unlike inet_aton's "1.2.3").
  if (::inet_pton(AF_INET, copy.c_str(), &address) != 1) return std::nullopt;
  std::memcpy(octets.data(), &address.s_addr, octets.size());  // network order = a.b.c.d
  return octets;
}

std::string resolve_udp_dest(const nlohmann::json& value, const json_reader::Location& at, const std::string& peer_ip) {
  if (!value.is_string()) at.fail_expected("an IPv4 address, a host name or \"@auto\"", value);
  const auto text = value.get<std::string>();
  if (text.empty() || parse_ipv4(text)) return text;  // "" is for the validation to judge
  if (text == "@auto") return peer_ipv4(peer_ip, at);
  if (text.find(':') != std::string::npos) at.fail("\"" + text + "\" is IPv6, but lidartwin streams over IPv4 only");
  if (looks_numeric(text)) at.fail("\"" + text + "\" is not a valid IPv4 address (expected a.b.c.d)");
  return resolve_host_name(text, at);
}

}  // namespace lidartwin
