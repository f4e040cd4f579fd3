#include "metadata/sectioned_document.h"

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include <fmt/ranges.h>

namespace lidartwin::metadata_detail {
namespace {

// Protocol doc 3.2: the top-level keys of a legacy file and the section the SDK moves each to.
// "data_format" moves whole, to lidar_data_format; everything else stays where it is.
constexpr std::pair<std::string_view, std::string_view> kLegacyMoves[] = {
    {"lidar_to_sensor_transform", "lidar_intrinsics"},
    {"imu_to_sensor_transform", "imu_intrinsics"},
    {"udp_port_imu", "config_params"},
    {"udp_port_lidar", "config_params"},
    {"lidar_mode", "config_params"},
    {"lidar_origin_to_beam_origin_mm", "beam_intrinsics"},
    {"beam_altitude_angles", "beam_intrinsics"},
    {"beam_azimuth_angles", "beam_intrinsics"},
    {"beam_to_lidar_transform", "beam_intrinsics"},
    {"prod_line", "sensor_info"},
    {"status", "sensor_info"},
    {"prod_pn", "sensor_info"},
    {"prod_sn", "sensor_info"},
    {"initialization_id", "sensor_info"},
    {"build_rev", "sensor_info"},
    {"build_date", "sensor_info"},
    {"image_rev", "sensor_info"},
};

bool moved_to(std::string_view key, std::string_view section) {
  return std::any_of(std::begin(kLegacyMoves), std::end(kLegacyMoves),
                     [&](const auto& move) { return move.first == key && move.second == section; });
}

// Where a section's object lives in the file: itself, or "data_format" in legacy files.
std::string_view stored_name(std::string_view section, bool legacy) {
  return legacy && section == "lidar_data_format" ? "data_format" : section;
}

// Sections the file holds as whole objects (the others a legacy file spreads over the top level).
bool stored_whole(std::string_view section, bool legacy) {
  return !legacy || section == "lidar_data_format" || section == "imu_data_format" || section == "calibration_status";
}

void check_section_types(const nlohmann::json& root, bool legacy, const JsonReader& reader) {
  for (std::string_view section : {"sensor_info", "beam_intrinsics", "imu_intrinsics", "lidar_intrinsics",
                                   "config_params", "lidar_data_format", "calibration_status", "imu_data_format"}) {
    if (!stored_whole(section, legacy)) continue;
    const auto it = root.find(stored_name(section, legacy));
    if (it == root.end() || it->is_object() || it->is_string()) continue;
    reader.fail("/" + std::string(stored_name(section, legacy)), "an object", describe(*it));
  }
}

}  // namespace

SectionedDocument::SectionedDocument(const nlohmann::json& root, const JsonReader& reader) : root_(root) {
  if (!root.is_object()) reader.fail("", "a JSON object", describe(root));
  std::vector<std::string_view> missing;
  for (std::string_view section : kNestedSections) {
    if (!root.contains(section)) missing.push_back(section);
  }
  // Protocol doc 3.1: a partial set is a critical error, one issue per missing section.
  if (!missing.empty() && missing.size() != kNestedSections.size()) {
    reader.fail("",
                fmt::format("a nested metadata document needs all 7 sections; missing /{}", fmt::join(missing, ", /")));
  }
  legacy_ = missing.size() == kNestedSections.size();
  check_section_types(root, legacy_, reader);
}

std::optional<Node> SectionedDocument::section_node(std::string_view section) const {
  if (!stored_whole(section, legacy_)) return std::nullopt;
  const Node root{&root_, ""};
  std::optional<Node> node = JsonReader::child(root, stored_name(section, legacy_));
  if (!node || !node->value->is_object()) return std::nullopt;
  return node;
}

bool SectionedDocument::has_section(std::string_view section) const { return section_node(section).has_value(); }

std::optional<Node> SectionedDocument::find(std::string_view section, std::string_view key) const {
  if (stored_whole(section, legacy_)) {
    const std::optional<Node> node = section_node(section);
    return node ? JsonReader::child(*node, key) : std::nullopt;
  }
  if (!moved_to(key, section)) return std::nullopt;
  return JsonReader::child(Node{&root_, ""}, key);
}

nlohmann::json SectionedDocument::section_object(std::string_view section) const {
  if (stored_whole(section, legacy_)) {
    const std::optional<Node> node = section_node(section);
    return node ? **node : nlohmann::json::object();
  }
  nlohmann::json object = nlohmann::json::object();
  for (const auto& [key, target] : kLegacyMoves) {
    if (target == section && root_.contains(key)) object[std::string(key)] = root_.at(key);
  }
  return object;
}

}  // namespace lidartwin::metadata_detail
