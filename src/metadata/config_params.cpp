// config_params: the firmware defaults, and the keys the data format depends on (protocol doc 2.6, 3.1).
#include "metadata/metadata_sections.h"

namespace lidartwin {
namespace metadata_detail {
namespace {

constexpr const char* kLidarModes = "one of 512x10, 512x20, 1024x10, 1024x20, 2048x10, 4096x5";
constexpr int64_t kMaxPort = 65535;
constexpr int64_t kFullCircleMdeg = 360000;

// FW 2.0/2.1 called udp_dest udp_ip; the SDK falls back to it.
std::optional<Node> udp_dest_node(const SectionedDocument& document) {
  if (auto node = document.find("config_params", "udp_dest")) return node;
  return document.find("config_params", "udp_ip");
}

}  // namespace

ConfigFacts parse_config_facts(const SectionedDocument& document, const JsonReader& reader) {
  ConfigFacts facts;
  if (auto node = document.find("config_params", "lidar_mode")) {
    facts.lidar_mode = parse_lidar_mode(reader.as_string(*node));
    if (!facts.lidar_mode) reader.fail(node->path, kLidarModes, describe(**node));
  }
  // Protocol doc 3.1: port 0 or an empty destination turns lidar output off.
  if (auto node = document.find("config_params", "udp_port_lidar")) {
    facts.lidar_enabled = reader.as_integer(*node, 0, kMaxPort) != 0;
  }
  if (auto node = udp_dest_node(document)) {
    facts.lidar_enabled = facts.lidar_enabled && !reader.as_string(*node).empty();
  }
  if (auto node = document.find("config_params", "udp_port_imu")) reader.as_integer(*node, 0, kMaxPort);
  if (auto node = document.find("config_params", "azimuth_window")) {
    if (!node->value->is_array() || node->value->size() != 2) {
      reader.fail(node->path, "[start, end] in millidegrees", describe(**node));
    }
    for (size_t i = 0; i < 2; ++i) {
      reader.as_integer(Node{&(**node)[i], node->path + "/" + std::to_string(i)}, 0, kFullCircleMdeg);
    }
  }
  return facts;
}

void complete_config_params(nlohmann::json& config, const LidarDataFormat& format) {
  if (!config.contains("lidar_mode")) {
    config["lidar_mode"] = to_string(LidarMode{format.columns_per_frame, format.fps});
  }
  if (!config.contains("udp_dest")) {
    const auto udp_ip = config.find("udp_ip");
    const bool has_udp_ip = udp_ip != config.end() && udp_ip->is_string();
    config["udp_dest"] = has_udp_ip ? *udp_ip : nlohmann::json("127.0.0.1");
  }
  if (!config.contains("udp_port_lidar")) config["udp_port_lidar"] = 7502;
  if (!config.contains("udp_port_imu")) config["udp_port_imu"] = 7503;
}

}  // namespace metadata_detail

// The active config of a FW 3.1 sensor after a factory reset, except udp_dest, which points at
// localhost (protocol doc 3.5).
nlohmann::json default_config_params() {
  return {
      {"accel_fsr", "NORMAL"},
      {"azimuth_window", {0, 360000}},
      {"columns_per_packet", 16},
      {"gyro_fsr", "NORMAL"},
      {"lidar_mode", "1024x10"},
      {"min_range_threshold_cm", 0},
      {"multipurpose_io_mode", "OFF"},
      {"nmea_baud_rate", "BAUD_9600"},
      {"nmea_ignore_valid_char", 0},
      {"nmea_in_polarity", "ACTIVE_HIGH"},
      {"nmea_leap_seconds", 0},
      {"operating_mode", "NORMAL"},
      {"phase_lock_enable", false},
      {"phase_lock_offset", 0},
      {"return_order", "STRONGEST_TO_WEAKEST"},
      {"signal_multiplier", 1},
      {"sync_pulse_in_polarity", "ACTIVE_HIGH"},
      {"sync_pulse_out_angle", 360},
      {"sync_pulse_out_frequency", 1},
      {"sync_pulse_out_polarity", "ACTIVE_HIGH"},
      {"sync_pulse_out_pulse_width", 10},
      {"timestamp_mode", "TIME_FROM_INTERNAL_OSC"},
      {"udp_dest", "127.0.0.1"},
      {"udp_port_imu", 7503},
      {"udp_port_lidar", 7502},
      {"udp_profile_imu", "LEGACY"},
      {"udp_profile_lidar", "RNG19_RFL8_SIG16_NIR16"},
  };
}

}  // namespace lidartwin
