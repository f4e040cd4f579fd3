#include "cli/unit_twin.h"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "lidartwin/error.h"
#include "lidartwin/profile/product_line.h"

namespace lidartwin::cli {
namespace {

using nlohmann::json;

json read_json(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open the file");
  try {
    return json::parse(in);
  } catch (const json::parse_error& e) {
    throw InputError(path.string() + ": not valid JSON (truncated?): " + e.what());
  }
}

// Where the file keeps a sensor_info key: nested under sensor_info, or at the top (FW 2.x flat).
std::string sensor_info_key(const json& document, const std::string& key) {
  return (document.contains("sensor_info") ? "/sensor_info/" : "/") + key;
}

std::string beam_angles_key(const json& document) {
  return document.contains("beam_intrinsics") ? "/beam_intrinsics/beam_altitude_angles" : "/beam_altitude_angles";
}

// The family profile's name, after checking that the unit's metadata can have one: a product line
// naming a shipped profile, and as many beams as the line says (FW before 1.14 listed 64 angles for
// 16- and 32-beam units, which no shipped profile describes).
std::string checked_family(const Metadata& unit, const json& document, const std::string& file) {
  const std::string& prod_line = unit.sensor_info.prod_line;
  const std::string key = sensor_info_key(document, "prod_line");
  if (prod_line.empty()) {
    throw InputError(file + ": " + key +
                     ": missing; a unit's metadata names its product line (e.g. \"OS-1-64\"), which chooses the "
                     "noise chain of its twin");
  }
  const std::string family = profile_family(prod_line);
  const auto available = available_profiles();
  if (family.empty() || std::find(available.begin(), available.end(), family) == available.end()) {
    throw InputError(fmt::format(
        "{}: {}: \"{}\" has no shipped profile{} to take the noise chain from; twins are made of OS-0, OS-1 and "
        "OS-2 units with 32, 64 or 128 beams (profiles in {}: {})",
        file, key, prod_line, family.empty() ? "" : " (no " + family + ".json)", profiles_dir().string(),
        fmt::join(available, ", ")));
  }
  const int beams = *beam_count_of(prod_line);
  if (unit.beams.pixels_per_column() != beams) {
    throw InputError(
        fmt::format("{}: {}: {} beams, but prod_line \"{}\" names {}; no shipped profile has that "
                    "layout (FW before 1.14 listed 64 angles for every product)",
                    file, beam_angles_key(document), unit.beams.pixels_per_column(), prod_line, beams));
  }
  return family;
}

json beams_json(const BeamIntrinsics& beams) {
  return {{"beam_altitude_angles", beams.altitude_deg},
          {"beam_azimuth_angles", beams.azimuth_deg},
          {"lidar_origin_to_beam_origin_mm", beams.lidar_origin_to_beam_origin_mm},
          {"beam_to_lidar_transform", beams.beam_to_lidar},
          {"lidar_to_sensor_transform", beams.lidar_to_sensor},
          {"imu_to_sensor_transform", beams.imu_to_sensor}};
}

SensorChoice twin_of(const json& document, const std::filesystem::path& path) {
  const std::string file = path.string();
  SensorChoice choice;
  choice.unit = parse_metadata(document, file);
  const std::string family = checked_family(*choice.unit, document, file);
  choice.document = twin_document(*choice.unit, file, read_json(profile_file(family)), family);
  // Validated as any profile: what `fit` writes from it reads back the same way.
  choice.profile = parse_profile(choice.document, file);
  return choice;
}

}  // namespace

bool is_sensor_metadata(const json& document) {
  if (!document.is_object() || document.contains("effects")) return false;
  for (const char* section : {"sensor_info", "beam_intrinsics", "imu_intrinsics", "lidar_intrinsics", "config_params",
                              "lidar_data_format", "calibration_status"}) {
    if (document.contains(section)) return true;
  }
  return document.contains("beam_altitude_angles") || document.contains("lidar_mode") || document.contains("prod_sn");
}

std::string profile_family(const std::string& prod_line) {
  if (!is_current_product_line(prod_line)) return "";
  return fmt::format("os{}-{}", prod_line[3], *beam_count_of(prod_line));
}

json twin_document(const Metadata& unit, const std::string& unit_file, const json& family,
                   const std::string& family_name) {
  json document = family;
  const SensorInfo& info = unit.sensor_info;
  document["prod_line"] = info.prod_line;
  if (!info.prod_pn.empty()) document["prod_pn"] = info.prod_pn;
  document["source"] = fmt::format(
      "twin of the unit in {} ({} sn {}, firmware {}): its beam intrinsics; effects, ranges, divergence, IMU noise "
      "and lidar modes of profiles/{}.json",
      unit_file, info.prod_line, info.prod_sn.empty() ? "unknown" : info.prod_sn,
      info.build_rev.empty() ? "unknown" : info.build_rev, family_name);
  document["beam_intrinsics"] = beams_json(unit.beams);
  // The mode the unit ran is one it supports, whatever the family's list says.
  const auto mode = unit.config_params.find("lidar_mode");
  json& modes = document["lidar_modes"];
  if (mode != unit.config_params.end() && mode->is_string() &&
      std::find(modes.begin(), modes.end(), *mode) == modes.end()) {
    modes.push_back(*mode);
  }
  return document;
}

json unit_start_config(const Metadata& unit) {
  json config = json::object();
  const auto mode = unit.config_params.find("lidar_mode");
  if (mode != unit.config_params.end() && mode->is_string()) config["lidar_mode"] = *mode;
  // lidar_data_format, not config_params, says what the packets were (protocol doc 3.1).
  if (unit.undecodable_lidar_profile.empty()) {
    config["udp_profile_lidar"] = std::string(to_string(unit.format.udp_profile_lidar));
  }
  config["columns_per_packet"] = unit.format.columns_per_packet;
  return config;
}

std::optional<std::pair<int, int>> firmware_version(const std::string& image_rev) {
  const auto digit = [&](size_t i) { return i < image_rev.size() && image_rev[i] >= '0' && image_rev[i] <= '9'; };
  for (size_t v = image_rev.find('v'); v != std::string::npos; v = image_rev.find('v', v + 1)) {
    size_t i = v + 1;
    int major = 0, minor = 0;
    if (!digit(i)) continue;
    for (; digit(i); ++i) major = major * 10 + (image_rev[i] - '0');
    if (i >= image_rev.size() || image_rev[i] != '.' || !digit(i + 1)) continue;
    for (++i; digit(i); ++i) minor = minor * 10 + (image_rev[i] - '0');
    return std::pair{major, minor};
  }
  return std::nullopt;
}

EffectChain profile_chain(const SensorProfile& profile) {
  return EffectChain::from_json(profile.effects, json_reader::Location{"profile " + profile.name, "/effects"});
}

SensorChoice load_sensor(const std::string& name_or_path) {
  const std::filesystem::path path = profile_file(name_or_path);
  json document = read_json(path);
  if (is_sensor_metadata(document)) return twin_of(document, path);
  SensorChoice choice;
  choice.profile = parse_profile(document, path.string());
  choice.document = std::move(document);
  return choice;
}

}  // namespace lidartwin::cli
