// The metadata a sensor reports for a config (protocol doc 3.4, 3.5, 6.4): what the daemon serves.
#include <cmath>

#include "lidartwin/metadata/metadata.h"
#include "metadata/metadata_sections.h"

namespace lidartwin {
namespace {

using metadata_detail::describe;
using metadata_detail::JsonReader;
using metadata_detail::Node;

// Protocol doc 5.2 (inferred): FW 3.2 samples its IMU at 640 Hz, so n = 640 / (fps * packets per
// frame): 8 at 2048x10 with 8 packets (imu_zm_no_lidar_0.json), 4 at 1024x20 (shot_limiting_test.json).
constexpr int kImuSampleRateHz = 640;
constexpr int kDefaultImuPacketsPerFrame = 8;
constexpr int kFullCircleMdeg = 360000;

Node at(const nlohmann::json& config, const std::string& key) { return Node{&config.at(key), "/" + key}; }

std::string string_at(const JsonReader& reader, const nlohmann::json& config, const std::string& key) {
  return reader.as_string(at(config, key));
}

int int_at(const JsonReader& reader, const nlohmann::json& config, const std::string& key, int min, int max) {
  return static_cast<int>(reader.as_integer(at(config, key), min, max));
}

// Protocol doc 3.4: the FW 3.x convention, shift = round(azimuth * W / 360).
std::vector<int> pixel_shift(const std::vector<double>& azimuth_deg, int columns_per_frame) {
  std::vector<int> shift;
  shift.reserve(azimuth_deg.size());
  for (double az : azimuth_deg) shift.push_back(static_cast<int>(std::lround(az * columns_per_frame / 360.0)));
  return shift;
}

// Protocol doc 6.4: the FW reports the azimuth window as the columns it covers.
std::array<int, 2> column_window(const JsonReader& reader, const nlohmann::json& config, int columns) {
  const Node window = at(config, "azimuth_window");
  if (!window.value->is_array() || window.value->size() != 2) {
    reader.fail(window.path, "[start, end] in millidegrees", describe(*window));
  }
  std::array<int, 2> ends{};
  for (size_t i = 0; i < 2; ++i) {
    const Node end{&(*window)[i], window.path + "/" + std::to_string(i)};
    ends[i] = static_cast<int>(reader.as_integer(end, 0, kFullCircleMdeg));
  }
  return column_window_from_azimuth_window(ends[0], ends[1], columns);
}

void read_profiles(const JsonReader& reader, const nlohmann::json& config, LidarDataFormat& format) {
  const auto lidar = udp_profile_lidar_from_string(string_at(reader, config, "udp_profile_lidar"));
  if (!lidar) reader.fail("/udp_profile_lidar", "a supported lidar profile", describe(config["udp_profile_lidar"]));
  format.udp_profile_lidar = *lidar;
  const auto imu = udp_profile_imu_from_string(string_at(reader, config, "udp_profile_imu"));
  if (!imu) reader.fail("/udp_profile_imu", "LEGACY, ACCEL32_GYRO32_NMEA or OFF", describe(config["udp_profile_imu"]));
  format.udp_profile_imu = *imu;
  format.header_type = implied_header_type(*lidar);
  if (config.contains("header_type")) {  // FW 3.2 makes it a config parameter
    const auto type = header_type_from_string(string_at(reader, config, "header_type"));
    if (!type) reader.fail("/header_type", "STANDARD or FUSA", describe(config["header_type"]));
    format.header_type = *type;
  }
}

void read_imu_counts(const JsonReader& reader, const nlohmann::json& config, LidarDataFormat& format) {
  if (format.udp_profile_imu != UdpProfileImu::kAccel32Gyro32Nmea) return;
  format.imu_packets_per_frame = config.contains("imu_packets_per_frame")
                                     ? int_at(reader, config, "imu_packets_per_frame", 1, 64)
                                     : kDefaultImuPacketsPerFrame;
  const int per_frame = format.fps * format.imu_packets_per_frame;
  if (kImuSampleRateHz % per_frame != 0) {
    reader.fail("/imu_packets_per_frame",
                "a divisor of " + std::to_string(kImuSampleRateHz / format.fps) + " (640 Hz IMU samples per frame)",
                std::to_string(format.imu_packets_per_frame));
  }
  format.imu_measurements_per_packet = kImuSampleRateHz / per_frame;
}

LidarDataFormat format_from_config(const JsonReader& reader, const nlohmann::json& config,
                                   const BeamIntrinsics& beams) {
  LidarDataFormat format;
  const auto mode = parse_lidar_mode(string_at(reader, config, "lidar_mode"));
  if (!mode) {
    reader.fail("/lidar_mode", "one of 512x10, 512x20, 1024x10, 1024x20, 2048x10, 4096x5",
                describe(config["lidar_mode"]));
  }
  format.columns_per_frame = mode->columns_per_frame;
  format.fps = mode->fps;
  format.pixels_per_column = beams.pixels_per_column();
  format.columns_per_packet = int_at(reader, config, "columns_per_packet", 1, 64);
  read_profiles(reader, config, format);
  format.column_window = column_window(reader, config, format.columns_per_frame);
  format.pixel_shift_by_row = pixel_shift(beams.azimuth_deg, format.columns_per_frame);
  read_imu_counts(reader, config, format);
  return format;
}

// FW 3.1 reports the IMU full-scale ranges here; FW 3.2 with ACCEL32_GYRO32_NMEA the two counts.
nlohmann::json imu_data_format(const JsonReader& reader, const nlohmann::json& config, const LidarDataFormat& format) {
  if (format.udp_profile_imu == UdpProfileImu::kAccel32Gyro32Nmea) {
    return {{"imu_measurements_per_packet", format.imu_measurements_per_packet},
            {"imu_packets_per_frame", format.imu_packets_per_frame}};
  }
  return {{"accel_fsr", string_at(reader, config, "accel_fsr")}, {"gyro_fsr", string_at(reader, config, "gyro_fsr")}};
}

// lidar_frame_azimuth_offset (FW 3.2 POST config docs): "a 90000 offset rotates the lidar
// coordinate frame 90 deg counter-clockwise about Z; the measurement frame then starts at sensor
// azimuth 270 deg". We report it in lidar_to_sensor_transform, the only thing the SDK's XYZ reads
// (inferred; not checked on a FW 3.2 unit): T' = T * Rz(offset), translation unchanged, so with the
// default T column m = 0 moves from sensor azimuth 180 deg to 270 deg for an offset of 90000.
Mat4 rotate_lidar_frame(const Mat4& lidar_to_sensor, const nlohmann::json& config) {
  const auto it = config.find("lidar_frame_azimuth_offset");
  if (it == config.end() || !it->is_number() || it->get<double>() == 0.0) return lidar_to_sensor;
  const double angle = it->get<double>() * 1e-3 * 3.14159265358979323846 / 180.0;
  const double c = std::cos(angle), s = std::sin(angle);
  Mat4 rotated = lidar_to_sensor;
  for (int row = 0; row < 3; ++row) {
    const double x = lidar_to_sensor[static_cast<size_t>(row * 4)];
    const double y = lidar_to_sensor[static_cast<size_t>(row * 4 + 1)];
    rotated[static_cast<size_t>(row * 4)] = x * c + y * s;
    rotated[static_cast<size_t>(row * 4 + 1)] = -x * s + y * c;
  }
  return rotated;
}

}  // namespace

Metadata make_metadata(const SensorInfo& sensor_info, const BeamIntrinsics& beams,
                       const nlohmann::json& config_params) {
  const JsonReader reader("config_params");
  if (!config_params.is_object()) reader.fail("", "an object", describe(config_params));
  if (beams.altitude_deg.empty() || beams.altitude_deg.size() != beams.azimuth_deg.size()) {
    reader.fail("", "beam intrinsics with as many azimuth as altitude angles",
                std::to_string(beams.altitude_deg.size()) + " and " + std::to_string(beams.azimuth_deg.size()));
  }
  nlohmann::json config = default_config_params();
  config.update(config_params);  // the caller's keys win; unknown keys are kept, as the FW does
  Metadata metadata;
  metadata.sensor_info = sensor_info;
  metadata.beams = beams;
  metadata.beams.lidar_to_sensor = rotate_lidar_frame(beams.lidar_to_sensor, config);
  metadata.format = format_from_config(reader, config, beams);
  metadata.imu_data_format = imu_data_format(reader, config, metadata.format);
  // A factory-calibrated sensor (the timestamp is the one of protocol doc 3.5).
  metadata.calibration_status = {{"reflectivity", {{"timestamp", "2024-01-01T00:00:00"}, {"valid", true}}}};
  metadata.config_params = std::move(config);
  return metadata;
}

}  // namespace lidartwin
