#pragma once
// CLI11 validators for the wire-format and identity flags of `record` and `serve`.
#include <CLI/CLI.hpp>

namespace lidartwin::cli {

CLI::Validator lidar_mode_validator();     // "1024x10"
CLI::Validator udp_profile_validator();    // one of the supported udp_profile_lidar names
CLI::Validator serial_number_validator();  // prod_sn: 1-12 decimal digits (40 bits in packets, 4.3)

}  // namespace lidartwin::cli
