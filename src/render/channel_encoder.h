#pragma once
// One column of Measurements (physical units) into a Scan's channels in protocol units
// (protocol doc 4.6): ranges in mm on the profile's step (8 mm for RNG15), reflectivity a byte,
// signal and near-IR photon counts clamped to their fields (NIR of RNG15 in steps of 16).
#include <span>
#include <vector>

#include "lidartwin/effects/measurement.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"

namespace lidartwin::render_detail {

class ChannelEncoder {
 public:
  explicit ChannelEncoder(const PacketFormat& format);
  void write(std::span<const Measurement> measured, int column, Scan& scan) const;
  void clear(int column, Scan& scan) const;  // every channel of the column to 0

 private:
  struct Channel {
    ChannelField field;
    float Measurement::*value;
    float scale;  // to protocol units: 1000 for ranges (m -> mm), else 1
    float step;
    float max;
    bool is_range;
  };
  static void write_range(const Channel& channel, std::span<const Measurement> measured, std::span<uint32_t> out);
  static void write_clamped(const Channel& channel, std::span<const Measurement> measured, std::span<uint32_t> out);

  std::vector<Channel> channels_;     // the profile's channels that carry a Measurement value
  std::vector<ChannelField> fields_;  // every channel the profile carries
};

}  // namespace lidartwin::render_detail
