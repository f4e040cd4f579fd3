// lidar_data_format (and the two imu_data_format counts) with the SDK's defaults (protocol doc 3.1).
#include <algorithm>

#include <fmt/ranges.h>

#include "metadata/metadata_sections.h"

namespace lidartwin::metadata_detail {
namespace {

constexpr int kMaxPixelsPerColumn = 128;
constexpr int kMaxColumns = 65535;

// The SDK's default_data_format(mode): Gen-1 OS-1-64 shifts, 4 rows repeating 3,2,1,0 steps of
// 3·W/512 columns (512: 9 6 3 0, 1024: 18 12 6 0, 2048: 36 24 12 0), 64 rows.
std::vector<int> gen1_pixel_shift(int columns_per_frame) {
  std::vector<int> shift(64);
  for (size_t row = 0; row < shift.size(); ++row) {
    shift[row] = static_cast<int>(3 - row % 4) * 3 * columns_per_frame / 512;
  }
  return shift;
}

std::string profile_names() { return fmt::format("{}", fmt::join(udp_profile_lidar_names(), ", ")); }

// Without a pixels_per_column key the product line's beam count applies. Exception: FW < 1.14 wrote
// no data format at all and sent 64 pixels per column whatever the product (the 16- and 32-beam
// OS-1 files of FW 1.12/1.13 list 64 beam angles); there the angle count, 64, is the height.
int default_pixels_per_column(const SectionedDocument& document, const std::string& prod_line) {
  const std::optional<int> beams = beam_count_of(prod_line);
  if (!beams) return 64;
  if (!document.has_section("lidar_data_format")) {
    const auto altitudes = document.find("beam_intrinsics", "beam_altitude_angles");
    if (altitudes && altitudes->value->is_array() && altitudes->value->size() == 64) return 64;
  }
  return *beams;
}

void read_geometry(const SectionedDocument& document, const JsonReader& reader, const ConfigFacts& config,
                   const std::string& prod_line, LidarDataFormat& format) {
  const auto find = [&](std::string_view key) { return document.find("lidar_data_format", key); };
  if (auto node = find("columns_per_frame")) {
    format.columns_per_frame = static_cast<int>(reader.as_integer(*node, 1, kMaxColumns));
  } else if (config.lidar_mode) {
    format.columns_per_frame = config.lidar_mode->columns_per_frame;
  } else {
    reader.fail(document.legacy() ? "/lidar_mode" : "/config_params/lidar_mode",
                "a lidar mode (needed unless lidar_data_format has columns_per_frame)", "nothing");
  }
  if (auto node = find("fps")) {
    format.fps = static_cast<int>(reader.as_integer(*node, 1, 100));
  } else if (config.lidar_mode) {
    format.fps = config.lidar_mode->fps;
  }
  // Without a lidar_mode the served config must still name one (complete_config_params).
  if (!config.lidar_mode && !parse_lidar_mode(to_string(LidarMode{format.columns_per_frame, format.fps}))) {
    reader.fail(find("columns_per_frame")->path, "a width and fps that form a lidar mode (no lidar_mode given)",
                std::to_string(format.columns_per_frame) + " columns at " + std::to_string(format.fps) + " fps");
  }
  format.pixels_per_column = default_pixels_per_column(document, prod_line);
  if (auto node = find("pixels_per_column")) {
    format.pixels_per_column = static_cast<int>(reader.as_integer(*node, 1, kMaxPixelsPerColumn));
  }
  if (auto node = find("columns_per_packet")) {
    format.columns_per_packet = static_cast<int>(reader.as_integer(*node, 1, format.columns_per_frame));
  }
}

void read_column_window(const SectionedDocument& document, const JsonReader& reader, LidarDataFormat& format) {
  format.column_window = {0, format.columns_per_frame - 1};
  const auto node = document.find("lidar_data_format", "column_window");
  if (!node) return;
  if (!node->value->is_array() || node->value->size() != 2) {
    reader.fail(node->path, "[first, last] measurement ids", describe(**node));
  }
  for (size_t i = 0; i < 2; ++i) {
    const Node end{&(**node)[i], node->path + "/" + std::to_string(i)};
    format.column_window[i] = static_cast<int>(reader.as_integer(end, 0, format.columns_per_frame - 1));
  }
}

// Padded with zeros or cut to one shift per row, as the SDK does.
void read_pixel_shift(const SectionedDocument& document, const JsonReader& reader, const ConfigFacts& config,
                      LidarDataFormat& format) {
  if (auto node = document.find("lidar_data_format", "pixel_shift_by_row")) {
    format.pixel_shift_by_row = reader.as_integers(*node);
  } else if (config.lidar_mode) {
    format.pixel_shift_by_row = gen1_pixel_shift(config.lidar_mode->columns_per_frame);
  }
  format.pixel_shift_by_row.resize(static_cast<size_t>(format.pixels_per_column), 0);
}

}  // namespace

ParsedFormat parse_data_format(const SectionedDocument& document, const JsonReader& reader, const ConfigFacts& config,
                               const std::string& prod_line) {
  ParsedFormat parsed;
  LidarDataFormat& format = parsed.format;
  read_geometry(document, reader, config, prod_line, format);
  read_column_window(document, reader, format);
  read_pixel_shift(document, reader, config, format);
  if (auto node = document.find("lidar_data_format", "udp_profile_lidar")) {
    const std::string name = reader.as_string(*node);
    const auto profile = udp_profile_lidar_from_string(name);
    // A profile we cannot decode is harmless when no lidar packets are sent (imu_zm_no_lidar_0.json).
    if (!profile && config.lidar_enabled) reader.fail(node->path, "one of " + profile_names(), describe(**node));
    format.udp_profile_lidar = profile.value_or(UdpProfileLidar::kLegacy);
    if (!profile) parsed.undecodable_lidar_profile = name;
  }
  if (auto node = document.find("lidar_data_format", "udp_profile_imu")) {
    const auto profile = udp_profile_imu_from_string(reader.as_string(*node));
    if (!profile) reader.fail(node->path, "one of LEGACY, ACCEL32_GYRO32_NMEA, OFF", describe(**node));
    format.udp_profile_imu = *profile;
  }
  format.header_type = implied_header_type(format.udp_profile_lidar);
  if (auto node = document.find("lidar_data_format", "header_type")) {
    const auto type = header_type_from_string(reader.as_string(*node));
    if (!type) reader.fail(node->path, "STANDARD or FUSA", describe(**node));
    format.header_type = *type;
  }
  if (auto node = document.find("imu_data_format", "imu_packets_per_frame")) {
    format.imu_packets_per_frame = static_cast<int>(reader.as_integer(*node, 0, 1024));
  }
  if (auto node = document.find("imu_data_format", "imu_measurements_per_packet")) {
    format.imu_measurements_per_packet = static_cast<int>(reader.as_integer(*node, 0, 1024));
  }
  return parsed;
}

// header_type is written only where it differs from what the profile implies: FW 3.1 documents do
// not have the key (it arrived with FW 3.2).
nlohmann::json data_format_to_json(const LidarDataFormat& format, const std::string& undecodable_lidar_profile) {
  nlohmann::json json = {
      {"column_window", format.column_window},
      {"columns_per_frame", format.columns_per_frame},
      {"columns_per_packet", format.columns_per_packet},
      {"fps", format.fps},
      {"pixel_shift_by_row", format.pixel_shift_by_row},
      {"pixels_per_column", format.pixels_per_column},
      {"udp_profile_imu", to_string(format.udp_profile_imu)},
      {"udp_profile_lidar", undecodable_lidar_profile.empty() ? std::string(to_string(format.udp_profile_lidar))
                                                              : undecodable_lidar_profile},
  };
  if (format.header_type != implied_header_type(format.udp_profile_lidar)) {
    json["header_type"] = to_string(format.header_type);
  }
  return json;
}

}  // namespace lidartwin::metadata_detail
