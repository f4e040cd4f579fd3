// A zeroed scan holding exactly the channels the format's profile carries.
#include "lidartwin/packet/scan.h"

#include <algorithm>
#include <cassert>

#include "packet/field_table.h"

namespace lidartwin {

Scan::Scan(const LidarDataFormat& format)
    : width(std::max(format.columns_per_frame, 0)), height(std::max(format.pixels_per_column, 0)) {
  assert(format.columns_per_frame > 0 && format.pixels_per_column > 0 && format.columns_per_packet > 0);
  const auto w = static_cast<size_t>(width);
  const auto cpp = static_cast<size_t>(std::max(format.columns_per_packet, 1));
  timestamp_ns.assign(w, 0);
  status.assign(w, 0);
  packet_received.assign((w + cpp - 1) / cpp, 0);
  for (const auto& spec : packet_detail::profile_spec(format.udp_profile_lidar).channels) {
    channels[static_cast<size_t>(spec.field)].assign(w * static_cast<size_t>(height), 0);
  }
}

}  // namespace lidartwin
