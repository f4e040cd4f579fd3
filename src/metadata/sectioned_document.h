#pragma once
// A metadata document seen through the 7 sections of the nested format, whichever format the file
// uses (protocol doc 3.1, 3.2). Legacy flat keys are found where the SDK's
// convert_legacy_to_nonlegacy moves them, while error paths name the key where the file has it.
#include <array>
#include <optional>
#include <string_view>

#include <nlohmann/json.hpp>

#include "metadata/json_reader.h"

namespace lidartwin::metadata_detail {

// Counted to tell the formats apart: all 7 -> nested, none -> legacy, some -> an error.
inline constexpr std::array<std::string_view, 7> kNestedSections{
    "sensor_info",   "beam_intrinsics",   "imu_intrinsics",    "lidar_intrinsics",
    "config_params", "lidar_data_format", "calibration_status"};

class SectionedDocument {
 public:
  // Throws InputError if root is not an object, names only some of the 7 sections, or has a
  // section that is neither an object nor a string.
  SectionedDocument(const nlohmann::json& root, const JsonReader& reader);

  bool legacy() const { return legacy_; }
  // section.key, e.g. ("beam_intrinsics", "beam_altitude_angles").
  std::optional<Node> find(std::string_view section, std::string_view key) const;
  // Whether the document has the section as an object (in legacy files: "data_format" for
  // lidar_data_format). FW 1.12/1.13 stored the sensor's error reply, a string, in its place.
  bool has_section(std::string_view section) const;
  // A copy of the section as an object ({} when absent); legacy config_params gathers the three
  // top-level keys the SDK moves there.
  nlohmann::json section_object(std::string_view section) const;

 private:
  std::optional<Node> section_node(std::string_view section) const;

  const nlohmann::json& root_;
  bool legacy_ = false;
};

}  // namespace lidartwin::metadata_detail
