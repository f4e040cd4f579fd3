// parse_profile: profiles/*.json → SensorProfile, validating every key (STYLE.md "Config").
// Beam intrinsics use the metadata's key names and defaults (protocol doc 3.1, 7.3) so a profile
// and the metadata served from it cannot drift apart.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"
#include "lidartwin/profile/product_line.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin {
namespace {

using json_reader::Location;
using json_reader::ObjectReader;
using json_reader::Range;
using json_reader::read_number;
using json_reader::read_numbers;
using json_reader::read_string;
using nlohmann::json;

const Range kAltitudeDeg{-90.0, 90.0};
const Range kAzimuthDeg{-180.0, 180.0};
const Range kMinRangeM{0.0, 1000.0, false, true};
const Range kMaxRangeM{0.0, 1000.0, true, false};
const Range kDivergenceRad{0.0, 0.1, true, false};
const Range kOffsetMm{0.0, 1000.0};
const Range kMatrixEntry{-1e6, 1e6};

// What the SDK accepts as lidar_mode (metadata.cpp; W ∈ {512, 1024, 2048, 4096}).
const std::vector<std::string> kLidarModes{"512x10", "512x20", "1024x10", "1024x20", "2048x10", "4096x5"};

// 16 numbers, row-major, an affine transform whose rotation part is orthonormal (det +1).
Mat4 read_transform(const json& value, const Location& at) {
  const std::vector<double> m = read_numbers(value, at, kMatrixEntry);
  if (m.size() != 16) at.fail("must have 16 numbers (row-major 4x4), got " + std::to_string(m.size()));
  if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0) at.fail("last row must be [0, 0, 0, 1]");
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double dot = 0.0;  // (R^T R)_ij
      for (int k = 0; k < 3; ++k) dot += m[4 * k + i] * m[4 * k + j];
      if (std::abs(dot - (i == j ? 1.0 : 0.0)) > 1e-3) at.fail("top-left 3x3 must be a rotation (orthonormal)");
    }
  }
  Mat4 out;
  std::copy(m.begin(), m.end(), out.begin());
  return out;
}

BeamIntrinsics read_beams(const json& value, const Location& at, std::string_view prod_line) {
  const ObjectReader reader(value, at,
                            {"beam_altitude_angles", "beam_azimuth_angles", "lidar_origin_to_beam_origin_mm",
                             "beam_to_lidar_transform", "lidar_to_sensor_transform", "imu_to_sensor_transform"});
  BeamIntrinsics beams;
  const std::string angles = "an array of 16, 32, 64 or 128 angles in degrees";
  beams.altitude_deg =
      read_numbers(reader.at("beam_altitude_angles", angles), at.child("beam_altitude_angles"), kAltitudeDeg);
  beams.azimuth_deg =
      read_numbers(reader.at("beam_azimuth_angles", angles), at.child("beam_azimuth_angles"), kAzimuthDeg);
  const size_t rows = beams.altitude_deg.size();
  if (rows != 16 && rows != 32 && rows != 64 && rows != 128) {
    at.child("beam_altitude_angles").fail("must have 16, 32, 64 or 128 beams, got " + std::to_string(rows));
  }
  if (beams.azimuth_deg.size() != rows) {
    at.child("beam_azimuth_angles")
        .fail("must have as many entries as beam_altitude_angles (" + std::to_string(rows) + "), got " +
              std::to_string(beams.azimuth_deg.size()));
  }
  const json* origin = reader.find("lidar_origin_to_beam_origin_mm");
  beams.lidar_origin_to_beam_origin_mm =
      origin ? read_number(*origin, at.child("lidar_origin_to_beam_origin_mm"), kOffsetMm)
             : default_lidar_origin_to_beam_origin_mm(prod_line);
  beams.beam_to_lidar = kIdentity4;
  beams.beam_to_lidar[3] = beams.lidar_origin_to_beam_origin_mm;  // SDK default (protocol doc 3.1)
  if (const json* b = reader.find("beam_to_lidar_transform")) {
    beams.beam_to_lidar = read_transform(*b, at.child("beam_to_lidar_transform"));
    // The SDK reads the origin offset from B[0][3]; both keys must say the same (protocol doc 7.2).
    if (origin && std::abs(beams.beam_to_lidar[3] - beams.lidar_origin_to_beam_origin_mm) > 1e-9) {
      at.child("beam_to_lidar_transform").fail("entry [0][3] must equal lidar_origin_to_beam_origin_mm");
    }
  }
  if (const json* t = reader.find("lidar_to_sensor_transform")) {
    beams.lidar_to_sensor = read_transform(*t, at.child("lidar_to_sensor_transform"));
  }
  if (const json* t = reader.find("imu_to_sensor_transform")) {
    beams.imu_to_sensor = read_transform(*t, at.child("imu_to_sensor_transform"));
  }
  return beams;
}

std::vector<std::string> read_modes(const json& value, const Location& at) {
  if (!value.is_array() || value.empty()) at.fail("must be a non-empty array of lidar modes such as \"1024x10\"");
  std::vector<std::string> modes;
  for (size_t i = 0; i < value.size(); ++i) {
    const std::string mode = read_string(value[i], at.child(i));
    if (std::find(kLidarModes.begin(), kLidarModes.end(), mode) == kLidarModes.end()) {
      at.child(i).fail("must be one of 512x10, 512x20, 1024x10, 1024x20, 2048x10, 4096x5, got \"" + mode + "\"");
    }
    if (std::find(modes.begin(), modes.end(), mode) != modes.end()) at.child(i).fail("duplicate mode \"" + mode + "\"");
    modes.push_back(mode);
  }
  return modes;
}

// The effects module validates each effect's parameters; here only the shape of the list.
json read_effects(const json& value, const Location& at) {
  if (!value.is_array()) at.fail("must be an array of effect objects, got " + json_reader::describe(value));
  for (size_t i = 0; i < value.size(); ++i) {
    const json& effect = value[i];
    if (!effect.is_object() || !effect.contains("name") || !effect.at("name").is_string()) {
      at.child(i).fail("must be an object with a string \"name\"");
    }
  }
  return value;
}

// prod_line "OS-<0|1|2>-<beams>[-<variant>]", e.g. "OS-0-32-U1"; the SDK takes the third field as
// the beam count (protocol doc 3.1).
void check_prod_line(const std::string& prod_line, size_t rows, const Location& at) {
  if (!is_current_product_line(prod_line))
    at.fail("must look like \"OS-1-64\" or \"OS-0-32-U1\", got \"" + prod_line + "\"");
  const int beams = *beam_count_of(prod_line);
  if (static_cast<size_t>(beams) != rows) {
    at.fail("names " + std::to_string(beams) + " beams but beam_intrinsics has " + std::to_string(rows));
  }
}

ImuNoise read_imu(const json& value, const Location& at) {
  const ObjectReader reader(value, at,
                            {"accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                             "gyroscope_random_walk", "gyroscope_g_sensitivity", "source"});
  const Range non_negative{0.0, 10.0};
  ImuNoise imu;
  const auto read = [&](std::string_view key, double& out) {
    if (const json* v = reader.find(key)) out = read_number(*v, at.child(key), non_negative);
  };
  read("accelerometer_noise_density", imu.accelerometer_noise_density);
  read("accelerometer_random_walk", imu.accelerometer_random_walk);
  read("gyroscope_noise_density", imu.gyroscope_noise_density);
  read("gyroscope_random_walk", imu.gyroscope_random_walk);
  read("gyroscope_g_sensitivity", imu.gyroscope_g_sensitivity);
  if (const json* v = reader.find("source")) read_string(*v, at.child("source"));
  return imu;
}

void read_unit_to_unit(const json& value, const Location& at, SensorProfile& profile) {
  const ObjectReader reader(value, at, {"range_spread", "source"});
  profile.unit_range_spread =
      read_number(reader.at("range_spread", "a factor in [1, 10]"), at.child("range_spread"), Range{1.0, 10.0});
  profile.unit_to_unit_source = read_string(reader.at("source", "a string"), at.child("source"));
}

}  // namespace

SensorProfile parse_profile(const nlohmann::json& document, std::string_view source) {
  const Location root{std::string(source), ""};
  // A sensor's metadata (protocol doc 3.1) where a profile belongs: say so, rather than name its
  // first key as unknown. (The CLI's --profile reads metadata as its unit's twin before this.)
  for (const char* key : {"sensor_info", "lidar_data_format", "config_params", "base_pn", "prod_sn"}) {
    if (document.is_object() && document.contains(key) && !document.contains("effects")) {
      throw InputError(std::string(source) + ": this is a sensor's metadata, not a profile (it has \"" + key +
                       "\"); a profile is profiles/*.json or what `lidartwin fit` writes");
    }
  }
  const ObjectReader top(
      document, root,
      {"prod_line", "prod_pn", "source", "min_range_m", "max_range_m", "beam_divergence_rad", "lidar_modes",
       "beam_intrinsics", "effects", "imu", "unit_to_unit", "fit"});  // fit: `lidartwin fit`'s notes
  SensorProfile profile;
  profile.name = std::filesystem::path(source).stem().string();
  profile.prod_line = read_string(top.at("prod_line", "a string such as \"OS-1-64\""), root.child("prod_line"));
  profile.prod_pn = read_string(top.at("prod_pn", "a part number string"), root.child("prod_pn"));
  if (const json* origin = top.find("source")) profile.source = read_string(*origin, root.child("source"));
  profile.min_range_m = read_number(top.at("min_range_m", "a number in " + kMinRangeM.to_string()),
                                    root.child("min_range_m"), kMinRangeM);
  profile.max_range_m = read_number(top.at("max_range_m", "a number in " + kMaxRangeM.to_string()),
                                    root.child("max_range_m"), kMaxRangeM);
  if (profile.min_range_m >= profile.max_range_m) {
    root.child("min_range_m").fail("must be below max_range_m (" + json(profile.max_range_m).dump() + ")");
  }
  profile.beam_divergence_rad = read_number(top.at("beam_divergence_rad", "a number in " + kDivergenceRad.to_string()),
                                            root.child("beam_divergence_rad"), kDivergenceRad);
  profile.lidar_modes = read_modes(top.at("lidar_modes", "an array of lidar modes"), root.child("lidar_modes"));
  profile.beams = read_beams(top.at("beam_intrinsics", "an object"), root.child("beam_intrinsics"), profile.prod_line);
  check_prod_line(profile.prod_line, profile.beams.altitude_deg.size(), root.child("prod_line"));
  profile.effects = read_effects(top.at("effects", "an array of effects"), root.child("effects"));
  if (const json* imu = top.find("imu")) profile.imu = read_imu(*imu, root.child("imu"));
  if (const json* u = top.find("unit_to_unit")) read_unit_to_unit(*u, root.child("unit_to_unit"), profile);
  return profile;
}

}  // namespace lidartwin
