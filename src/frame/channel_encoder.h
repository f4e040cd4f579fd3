#pragma once
// One column of Measurements (physical units) into a Scan's channels in protocol units
// (protocol doc 4.6): ranges in mm on the profile's step (8 mm for RNG15), reflectivity a byte,
// signal and near-IR photon counts clamped to their fields (NIR of RNG15 in steps of 16).
#include <span>
#include <vector>

#include "lidartwin/effects/measurement.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"

namespace lidartwin::frame_detail {

// A channel's conversion: value (in protocol units, after scale) -> multiple of step, at most max.
struct ChannelLimits {
  float scale;  // 1000 for ranges (m -> mm), else 1
  float step;
  float max;
};

class ChannelEncoder {
 public:
  explicit ChannelEncoder(const PacketFormat& format);
  void write(const MeasuredColumn& measured, int column, Scan& scan) const;
  void clear(int column, Scan& scan) const;  // every channel of the column to 0

  using Writer = void (*)(const ChannelLimits&, const MeasuredColumn&, std::span<uint32_t>);

 private:
  struct Channel {
    ChannelField field;
    ChannelLimits limits;
    Writer write;  // instantiated per MeasuredColumn array, so the loop reads one float array
  };
  std::vector<Channel> channels_;     // the profile's channels that carry a Measurement value
  std::vector<ChannelField> fields_;  // every channel the profile carries
};

}  // namespace lidartwin::frame_detail
