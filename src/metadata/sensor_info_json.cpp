// sensor_info section and what the product line implies (protocol doc 2.5, 3.1).
#include <algorithm>
#include <cctype>
#include <vector>

#include "metadata/metadata_sections.h"

namespace lidartwin::metadata_detail {
namespace {

bool all_digits(const std::string& text) {
  return !text.empty() && std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c); });
}

std::vector<std::string> split_dashes(const std::string& text) {
  std::vector<std::string> parts(1);
  for (char c : text) {
    if (c == '-') {
      parts.emplace_back();
    } else {
      parts.back() += c;
    }
  }
  return parts;
}

// Packet headers carry init_id in 24 bits (protocol doc 6.2).
constexpr int64_t kMaxInitId = (1 << 24) - 1;

}  // namespace

// The SDK matches ^(\w+)-(\d+|DOME)?(?:-(\d+))?... and takes the third group as the beam count;
// splitting on '-' gives the same answer for every product line seen in metadata files.
std::optional<int> beam_count_of(const std::string& prod_line) {
  const std::vector<std::string> parts = split_dashes(prod_line);
  if (parts.size() < 3 || !(all_digits(parts[1]) || parts[1] == "DOME")) return std::nullopt;
  if (!all_digits(parts[2]) || parts[2].size() > 4) return std::nullopt;
  return std::stoi(parts[2]);
}

double default_lidar_origin_to_beam_origin_mm(const std::string& prod_line) {
  if (prod_line.starts_with("OS-0-")) return 27.67;
  if (prod_line.starts_with("OS-1-")) return 15.806;
  if (prod_line.starts_with("OS-2-")) return 13.762;
  return 12.163;  // Gen 1
}

SensorInfo parse_sensor_info(const SectionedDocument& document, const JsonReader& reader) {
  SensorInfo info;
  const auto read_string = [&](std::string_view key, std::string& out) {
    if (auto node = document.find("sensor_info", key)) out = reader.as_string(*node);
  };
  read_string("prod_line", info.prod_line);
  read_string("prod_pn", info.prod_pn);
  read_string("prod_sn", info.prod_sn);
  read_string("image_rev", info.image_rev);
  read_string("build_rev", info.build_rev);
  read_string("build_date", info.build_date);
  read_string("status", info.status);
  if (!info.prod_sn.empty() && !all_digits(info.prod_sn)) {
    reader.fail(document.find("sensor_info", "prod_sn")->path, "a string of decimal digits",
                describe(info.prod_sn));
  }
  if (auto node = document.find("sensor_info", "initialization_id")) {
    info.initialization_id = static_cast<uint32_t>(reader.as_integer(*node, 0, kMaxInitId));
  }
  return info;
}

// prod_sn stays a string and initialization_id an integer, as FW 3.x serves them.
nlohmann::json sensor_info_to_json(const SensorInfo& info) {
  return {{"build_date", info.build_date}, {"build_rev", info.build_rev},
          {"image_rev", info.image_rev},   {"initialization_id", info.initialization_id},
          {"prod_line", info.prod_line},   {"prod_pn", info.prod_pn},
          {"prod_sn", info.prod_sn},       {"status", info.status}};
}

}  // namespace lidartwin::metadata_detail
