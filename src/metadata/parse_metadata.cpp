// parse_metadata: the SDK's order of reading (protocol doc 3.1): sensor_info, config_params, the
// data format (which needs the product line and lidar mode), then the intrinsics (which need the
// pixels per column).
#include <fstream>
#include <sstream>

#include "lidartwin/error.h"
#include "lidartwin/metadata/metadata.h"
#include "metadata/metadata_sections.h"

namespace lidartwin {

using metadata_detail::JsonReader;
using metadata_detail::SectionedDocument;

Metadata parse_metadata(const nlohmann::json& document, std::string_view source) {
  const JsonReader reader(source);
  const SectionedDocument sections(document, reader);
  Metadata metadata;
  metadata.sensor_info = metadata_detail::parse_sensor_info(sections, reader);
  const metadata_detail::ConfigFacts config = metadata_detail::parse_config_facts(sections, reader);
  metadata_detail::ParsedFormat parsed =
      metadata_detail::parse_data_format(sections, reader, config, metadata.sensor_info.prod_line);
  metadata.format = std::move(parsed.format);
  metadata.undecodable_lidar_profile = std::move(parsed.undecodable_lidar_profile);
  metadata.beams = metadata_detail::parse_beam_intrinsics(sections, reader, metadata.format.pixels_per_column,
                                                          metadata.sensor_info.prod_line);
  metadata.config_params = sections.section_object("config_params");
  metadata_detail::complete_config_params(metadata.config_params, metadata.format);
  metadata.imu_data_format = sections.section_object("imu_data_format");
  metadata.calibration_status = sections.section_object("calibration_status");
  return metadata;
}

Metadata load_metadata(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(name + ": cannot open metadata file");
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(name + ": not valid JSON: " + e.what());
  }
  return parse_metadata(document, name);
}

bool Metadata::lidar_enabled() const {
  const auto port = config_params.find("udp_port_lidar");
  const auto dest = config_params.find("udp_dest");
  const bool port_off = port != config_params.end() && port->is_number() && port->get<double>() == 0.0;
  const bool dest_off = dest != config_params.end() && dest->is_string() && dest->get<std::string>().empty();
  return !port_off && !dest_off;
}

}  // namespace lidartwin
