#pragma once
// Sensor metadata JSON: produce the nested FW 3.1 document; parse nested and legacy flat files
// (protocol doc 3).
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "lidartwin/packet/data_format.h"
#include "lidartwin/profile/beam_intrinsics.h"

namespace lidartwin {

struct SensorInfo {
  std::string prod_line;  // e.g. "OS-1-64"
  std::string prod_pn;
  std::string prod_sn;    // decimal digits, a string as on the wire
  std::string image_rev;  // e.g. "ousteros-image-prod-bootes-v3.1.0+20240426041747"
  std::string build_rev;  // e.g. "v3.1.0"
  std::string build_date;
  std::string status = "RUNNING";
  uint32_t initialization_id = 0;
  friend bool operator==(const SensorInfo&, const SensorInfo&) = default;
};

struct Metadata {
  SensorInfo sensor_info;
  BeamIntrinsics beams;
  LidarDataFormat format;
  nlohmann::json config_params = nlohmann::json::object();  // flat config, unknown keys kept
  nlohmann::json imu_data_format = nlohmann::json::object();
  nlohmann::json calibration_status = nlohmann::json::object();
  friend bool operator==(const Metadata&, const Metadata&) = default;
};

// Parse a nested or legacy-flat document. Throws InputError naming `source` and the JSON path of
// the bad or missing key.
Metadata parse_metadata(const nlohmann::json& document, std::string_view source);
Metadata load_metadata(const std::filesystem::path& path);

// A complete FW 3.1 config_params object with the firmware defaults (protocol doc 3.5):
// udp_dest 127.0.0.1, ports 7502/7503, 1024x10, RNG19_RFL8_SIG16_NIR16, LEGACY IMU, NORMAL.
nlohmann::json default_config_params();

// The metadata a sensor reports for a config: lidar_data_format derived from config_params
// (W and fps from lidar_mode, columns_per_packet, profiles, column_window from azimuth_window,
// pixel_shift_by_row = round(az * W / 360)), imu_data_format and calibration_status.
// Throws InputError naming the config key if config_params cannot describe a stream.
Metadata make_metadata(const SensorInfo& sensor_info, const BeamIntrinsics& beams,
                       const nlohmann::json& config_params);

// The document GET /api/v1/sensor/metadata serves: all 7 sections plus imu_data_format.
nlohmann::json to_nested_json(const Metadata& metadata);

}  // namespace lidartwin
