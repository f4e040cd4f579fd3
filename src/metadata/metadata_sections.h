#pragma once
// Reading and writing the sections of a metadata document (protocol doc 3.1), one file each.
#include <optional>

#include <nlohmann/json.hpp>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/profile/product_line.h"
#include "metadata/json_reader.h"
#include "metadata/sectioned_document.h"

namespace lidartwin::metadata_detail {

SensorInfo parse_sensor_info(const SectionedDocument& document, const JsonReader& reader);
nlohmann::json sensor_info_to_json(const SensorInfo& info);

// What the data format needs from config_params, read and type-checked once.
struct ConfigFacts {
  std::optional<LidarMode> lidar_mode;
  bool lidar_enabled = true;  // false if udp_port_lidar == 0 or udp_dest == "" (protocol doc 3.1)
};
ConfigFacts parse_config_facts(const SectionedDocument& document, const JsonReader& reader);
// Adds lidar_mode, udp_dest, udp_port_lidar and udp_port_imu where missing: clients dereference
// them unconditionally (protocol doc 3.1), so every document we serve carries them.
void complete_config_params(nlohmann::json& config, const LidarDataFormat& format);

struct ParsedFormat {
  LidarDataFormat format;
  std::string undecodable_lidar_profile;
};
ParsedFormat parse_data_format(const SectionedDocument& document, const JsonReader& reader, const ConfigFacts& config,
                               const std::string& prod_line);
nlohmann::json data_format_to_json(const LidarDataFormat& format, const std::string& undecodable_lidar_profile);

BeamIntrinsics parse_beam_intrinsics(const SectionedDocument& document, const JsonReader& reader, int pixels_per_column,
                                     const std::string& prod_line);
// Writes the three intrinsics sections into the document.
void beam_intrinsics_to_json(const BeamIntrinsics& beams, nlohmann::json& document);

}  // namespace lidartwin::metadata_detail
