#include "lidartwin/profile/product_line.h"

#include <algorithm>
#include <string>
#include <vector>

namespace lidartwin {
namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool all_digits(std::string_view text) { return !text.empty() && std::all_of(text.begin(), text.end(), is_digit); }
bool is_word(char c) { return is_digit(c) || c == '_' || (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); }

// Parsed by hand: std::regex trips GCC 12's sanitizer build.
std::vector<std::string_view> split_dashes(std::string_view text) {
  std::vector<std::string_view> parts;
  size_t begin = 0;
  for (size_t dash = text.find('-'); dash != std::string_view::npos; dash = text.find('-', begin)) {
    parts.push_back(text.substr(begin, dash - begin));
    begin = dash + 1;
  }
  parts.push_back(text.substr(begin));
  return parts;
}

}  // namespace

std::optional<int> beam_count_of(std::string_view prod_line) {
  const auto parts = split_dashes(prod_line);
  if (parts.size() < 3 || !(all_digits(parts[1]) || parts[1] == "DOME")) return std::nullopt;
  if (!all_digits(parts[2]) || parts[2].size() > 4) return std::nullopt;
  return std::stoi(std::string(parts[2]));
}

double default_lidar_origin_to_beam_origin_mm(std::string_view prod_line) {
  if (prod_line.starts_with("OS-0-")) return 27.67;
  if (prod_line.starts_with("OS-1-")) return 15.806;
  if (prod_line.starts_with("OS-2-")) return 13.762;
  return 12.163;  // Gen 1
}

bool is_current_product_line(std::string_view prod_line) {
  const auto parts = split_dashes(prod_line);
  if (parts.size() < 3 || parts.size() > 4 || parts[0] != "OS") return false;
  if (parts[1].size() != 1 || parts[1][0] < '0' || parts[1][0] > '2') return false;
  if (!all_digits(parts[2]) || parts[2].size() > 4) return false;
  return parts.size() == 3 || (!parts[3].empty() && std::all_of(parts[3].begin(), parts[3].end(), is_word));
}

}  // namespace lidartwin
