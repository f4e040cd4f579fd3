#pragma once
// CLI11 validators for the wire-format flags that `record` and `serve` share.
#include <CLI/CLI.hpp>

namespace lidartwin::cli {

CLI::Validator lidar_mode_validator();   // "1024x10"
CLI::Validator udp_profile_validator();  // one of the supported udp_profile_lidar names

}  // namespace lidartwin::cli
