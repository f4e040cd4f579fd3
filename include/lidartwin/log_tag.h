#pragma once
// A rig's sensors share one log: each line of a sensor's part of it names the sensor after its
// subject, as in "streamer (roof): ..." or "HTTP (left): ...". A lone sensor's lines carry no tag.
#include <string>
#include <string_view>

namespace lidartwin {

inline std::string log_tag(std::string_view sensor_name) {
  return sensor_name.empty() ? std::string() : " (" + std::string(sensor_name) + ")";
}

}  // namespace lidartwin
