#pragma once
// The port in a daemon log line "<prefix><address>:<port><more>", e.g. "answering on
// http://127.0.0.1:8080/". A string search rather than <regex>, which adds about 6 s of compile
// time to every test that includes it. The port counts only once a character follows it, so a line
// still being written is not read as a shorter port.
#include <cctype>
#include <optional>
#include <string>
#include <string_view>

namespace lidartwin::e2e {

inline std::optional<int> port_after(const std::string& log, std::string_view prefix) {
  const auto digit = [&](size_t i) { return std::isdigit(static_cast<unsigned char>(log[i])) != 0; };
  for (size_t at = log.find(prefix); at != std::string::npos; at = log.find(prefix, at + 1)) {
    size_t p = at + prefix.size();
    while (p < log.size() && (digit(p) || log[p] == '.')) ++p;  // the dotted address
    if (p >= log.size() || log[p] != ':') continue;
    const size_t first = ++p;
    int port = 0;
    while (p < log.size() && digit(p) && port <= 65535) port = 10 * port + (log[p++] - '0');
    if (p > first && p < log.size() && port <= 65535) return port;
  }
  return std::nullopt;
}

}  // namespace lidartwin::e2e
