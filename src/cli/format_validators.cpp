#include "cli/format_validators.h"

#include <string>

#include <fmt/ranges.h>

#include "lidartwin/packet/data_format.h"

namespace lidartwin::cli {

CLI::Validator lidar_mode_validator() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        return parse_lidar_mode(value) ? "" : "expected WIDTHxRATE with width 512/1024/2048/4096, e.g. 1024x10";
      },
      "MODE");
}

CLI::Validator udp_profile_validator() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        if (udp_profile_lidar_from_string(value)) return "";
        return fmt::format("expected one of {}", fmt::join(udp_profile_lidar_names(), ", "));
      },
      "PROFILE");
}

CLI::Validator serial_number_validator() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        const bool digits =
            !value.empty() && value.size() <= 12 && value.find_first_not_of("0123456789") == std::string::npos;
        return digits ? "" : "expected 1 to 12 decimal digits, e.g. 122201000011";
      },
      "DIGITS");
}

}  // namespace lidartwin::cli
