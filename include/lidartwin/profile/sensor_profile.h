#pragma once
// A product's description: beams, ranges, lidar modes and the effect chain (profiles/*.json).
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/profile/beam_intrinsics.h"

namespace lidartwin {

// The IMU's errors in Kalibr's continuous-time convention (imu.yaml): white noise densities and
// bias random walks per axis, and the gyro's sensitivity to specific force. All zero: exact.
struct ImuNoise {
  double accelerometer_noise_density = 0.0;  // m/s^2/sqrt(Hz)
  double accelerometer_random_walk = 0.0;    // m/s^3/sqrt(Hz)
  double gyroscope_noise_density = 0.0;      // rad/s/sqrt(Hz)
  double gyroscope_random_walk = 0.0;        // rad/s^2/sqrt(Hz)
  double gyroscope_g_sensitivity = 0.0;      // rad/s per m/s^2 of specific force, each axis
  bool any() const {
    return accelerometer_noise_density > 0 || accelerometer_random_walk > 0 || gyroscope_noise_density > 0 ||
           gyroscope_random_walk > 0 || gyroscope_g_sensitivity > 0;
  }
};

struct SensorProfile {
  std::string name;       // file stem, e.g. "os1-64"
  std::string prod_line;  // what sensor_info.prod_line reports, e.g. "OS-1-64"
  std::string prod_pn;
  std::string source;  // where the beam intrinsics came from (a sample file, a paper)
  BeamIntrinsics beams;
  double min_range_m = 0.3;             // below this: no return
  double max_range_m = 100.0;           // beyond this: no return
  double beam_divergence_rad = 0.0023;  // FWHM
  std::vector<std::string> lidar_modes{"512x10", "512x20", "1024x10", "1024x20", "2048x10"};
  nlohmann::json effects = nlohmann::json::array();  // the effect chain, parsed by effects/
  ImuNoise imu;                                      // "imu"; absent: an exact IMU
  // "unit_to_unit": how far units of the product line are known to differ from the one the
  // effects were fitted on, as a factor on the range spread (2: half to twice); 0 where unknown.
  // compare names it beside a unit whose spread is tighter or wider than the profile's.
  double unit_range_spread = 0.0;
  std::string unit_to_unit_source;
};

// Loads profiles/<name>.json (or a path to a .json file). Unknown keys, missing keys and values
// out of range throw InputError naming the file, the key and the allowed range.
SensorProfile load_profile(std::string_view name_or_path);
// The file load_profile reads for a name or path (throws InputError like it for a missing name).
std::filesystem::path profile_file(std::string_view name_or_path);
SensorProfile parse_profile(const nlohmann::json& document, std::string_view source);
// Where the shipped data lives (profiles, scenes, rigs, tools): $LIDARTWIN_SOURCE_DIR (an installed
// copy, a container's), else the source tree this binary was built from.
std::filesystem::path source_dir();
std::filesystem::path profiles_dir();  // $LIDARTWIN_PROFILES, else source_dir()/profiles
std::vector<std::string> available_profiles();
// The datasheet's range-noise table (Table I) of a product line's family ("OS-1-32" -> OS-1): the
// range_noise_piecewise effect of the first available profile of that family that has one (the
// datasheet profiles; the paper profiles have the linear law). None if no profile has one.
std::optional<nlohmann::json> datasheet_range_noise(std::string_view prod_line);

}  // namespace lidartwin
