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

// Packet headers carry init_id in 24 bits (protocol doc 6.2).
constexpr int64_t kMaxInitId = (1 << 24) - 1;

}  // namespace

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
    reader.fail(document.find("sensor_info", "prod_sn")->path, "a string of decimal digits", describe(info.prod_sn));
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
