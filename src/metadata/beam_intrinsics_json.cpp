// beam_intrinsics, imu_intrinsics and lidar_intrinsics with the SDK's defaults (protocol doc 3.1, 7.3).
#include "metadata/metadata_sections.h"

namespace lidartwin::metadata_detail {
namespace {

// Angles are crit in the SDK: missing, mistyped or of a length other than the pixels per column.
std::vector<double> read_angles(const SectionedDocument& document, const JsonReader& reader, std::string_view key,
                                int pixels_per_column) {
  const auto node = document.find("beam_intrinsics", key);
  if (!node) {
    reader.fail((document.legacy() ? "/" : "/beam_intrinsics/") + std::string(key),
                std::to_string(pixels_per_column) + " numbers", "nothing");
  }
  return reader.as_numbers(*node, static_cast<size_t>(pixels_per_column));
}

}  // namespace

BeamIntrinsics parse_beam_intrinsics(const SectionedDocument& document, const JsonReader& reader, int pixels_per_column,
                                     const std::string& prod_line) {
  BeamIntrinsics beams;
  beams.altitude_deg = read_angles(document, reader, "beam_altitude_angles", pixels_per_column);
  beams.azimuth_deg = read_angles(document, reader, "beam_azimuth_angles", pixels_per_column);
  beams.lidar_origin_to_beam_origin_mm = default_lidar_origin_to_beam_origin_mm(prod_line);
  if (auto node = document.find("beam_intrinsics", "lidar_origin_to_beam_origin_mm")) {
    beams.lidar_origin_to_beam_origin_mm = reader.as_number(*node);
  }
  // Default: identity with the beam origin offset along x (the SDK's default_beam_to_lidar).
  beams.beam_to_lidar = kIdentity4;
  beams.beam_to_lidar[3] = beams.lidar_origin_to_beam_origin_mm;
  if (auto node = document.find("beam_intrinsics", "beam_to_lidar_transform"))
    beams.beam_to_lidar = reader.as_mat4(*node);
  if (auto node = document.find("imu_intrinsics", "imu_to_sensor_transform"))
    beams.imu_to_sensor = reader.as_mat4(*node);
  if (auto node = document.find("lidar_intrinsics", "lidar_to_sensor_transform")) {
    beams.lidar_to_sensor = reader.as_mat4(*node);
  }
  return beams;
}

void beam_intrinsics_to_json(const BeamIntrinsics& beams, nlohmann::json& document) {
  document["beam_intrinsics"] = {
      {"beam_altitude_angles", beams.altitude_deg},
      {"beam_azimuth_angles", beams.azimuth_deg},
      {"beam_to_lidar_transform", beams.beam_to_lidar},
      {"lidar_origin_to_beam_origin_mm", beams.lidar_origin_to_beam_origin_mm},
  };
  document["imu_intrinsics"] = {{"imu_to_sensor_transform", beams.imu_to_sensor}};
  document["lidar_intrinsics"] = {{"lidar_to_sensor_transform", beams.lidar_to_sensor}};
}

}  // namespace lidartwin::metadata_detail
