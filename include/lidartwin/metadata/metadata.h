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
  // The lidar_data_format.udp_profile_lidar name when it is a profile this project cannot decode
  // (e.g. FW 3.2's RNG19_RFL8_SIG16_NIR16_ZONE16); accepted only while lidar output is off, as in
  // the IMU-only sample imu_zm_no_lidar_0.json. Empty otherwise; format.udp_profile_lidar is then
  // a placeholder (LEGACY).
  std::string undecodable_lidar_profile;
  friend bool operator==(const Metadata&, const Metadata&) = default;

  // Protocol doc 3.1: config_params.udp_port_lidar == 0 or udp_dest == "" means the sensor sends
  // no lidar packets (the SDK then treats the profile as OFF).
  bool lidar_enabled() const;
};

// Parse a nested or legacy-flat document as the SDK's parse_and_validate_metadata reads it
// (protocol doc 3.1, 3.2): missing optional keys get the SDK's defaults; a partial set of the 7
// sections, missing or mistyped beam angles, and present-but-invalid values throw InputError naming
// `source` and the JSON path of the key where the file has it (legacy files: top-level paths).
// One deliberate difference: FW < 1.14 files of 16/32-beam products, which list 64 angles and
// have no data format, get 64 pixels per column (what that FW sent) where the SDK rejects them.
// config_params always comes back with lidar_mode, udp_dest, udp_port_lidar and udp_port_imu
// (filled from the format, udp_ip, or 127.0.0.1/7502/7503), so to_nested_json can serve it.
Metadata parse_metadata(const nlohmann::json& document, std::string_view source);
// Reads and parses a file; InputError names the file if it is missing or not JSON.
Metadata load_metadata(const std::filesystem::path& path);

// A complete FW 3.1 config_params object with the firmware defaults (protocol doc 3.5):
// udp_dest 127.0.0.1, ports 7502/7503, 1024x10, RNG19_RFL8_SIG16_NIR16, LEGACY IMU, NORMAL.
nlohmann::json default_config_params();

// The metadata a sensor reports for a config: lidar_data_format derived from config_params
// (W and fps from lidar_mode, columns_per_packet, profiles, column_window from azimuth_window,
// pixel_shift_by_row = round(az * W / 360)), imu_data_format and calibration_status.
// Throws InputError naming the config key if config_params cannot describe a stream.
Metadata make_metadata(const SensorInfo& sensor_info, const BeamIntrinsics& beams, const nlohmann::json& config_params);

// The document GET /api/v1/sensor/metadata serves: all 7 sections plus imu_data_format.
nlohmann::json to_nested_json(const Metadata& metadata);

}  // namespace lidartwin
