#pragma once
// One column of Measurements (physical units) into a Scan's channels in protocol units
// (protocol doc 4.6): ranges in mm on the profile's step (8 mm for RNG15), reflectivity a byte,
// signal and near-IR photon counts clamped to their fields (NIR of RNG15 in steps of 16).
#include <span>
#include <vector>

#include "frame/channel_kernels.h"
#include "lidartwin/effects/measurement.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"

namespace lidartwin::frame_detail {

class ChannelEncoder {
 public:
  explicit ChannelEncoder(const PacketFormat& format);
  void write(const MeasuredColumn& measured, int column, Scan& scan) const;
  void clear(int column, Scan& scan) const;  // every channel of the column to 0

 private:
  struct Channel {
    ChannelField field;
    std::vector<float> MeasuredColumn::*values;
    ChannelConversion conversion;  // values and out filled in per column
  };
  std::vector<Channel> channels_;     // the profile's channels that carry a Measurement value
  std::vector<ChannelField> fields_;  // every channel the profile carries
};

}  // namespace lidartwin::frame_detail
