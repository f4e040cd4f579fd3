// The nested FW 3.1 document (protocol doc 3.5): the 7 sections plus imu_data_format.
#include "lidartwin/metadata/metadata.h"
#include "metadata/metadata_sections.h"

namespace lidartwin {

nlohmann::json to_nested_json(const Metadata& metadata) {
  nlohmann::json document = nlohmann::json::object();
  document["sensor_info"] = metadata_detail::sensor_info_to_json(metadata.sensor_info);
  metadata_detail::beam_intrinsics_to_json(metadata.beams, document);
  document["lidar_data_format"] =
      metadata_detail::data_format_to_json(metadata.format, metadata.undecodable_lidar_profile);
  // The two IMU counts live in imu_data_format (FW 3.2); keep them with the format's values.
  nlohmann::json imu = metadata.imu_data_format.is_object() ? metadata.imu_data_format : nlohmann::json::object();
  if (metadata.format.imu_packets_per_frame != 0) imu["imu_packets_per_frame"] = metadata.format.imu_packets_per_frame;
  if (metadata.format.imu_measurements_per_packet != 0) {
    imu["imu_measurements_per_packet"] = metadata.format.imu_measurements_per_packet;
  }
  document["imu_data_format"] = imu;
  document["calibration_status"] = metadata.calibration_status;
  document["config_params"] = metadata.config_params;
  return document;
}

}  // namespace lidartwin
