#pragma once
// `serve --record`'s ground truth, as `record` writes it (README "Offline tools"): DIR/poses.tum,
// the sensor's pose at the first column of each frame sent, and DIR/column_poses.tum, the pose each
// observed column that went out was cast from, both stamped on the packets' clock in seconds.
#include <cstdint>
#include <filesystem>

#include "lidartwin/frame/forward_model.h"
#include "lidartwin/pose/pose.h"

namespace lidartwin::streamer_detail {

class GroundTruth {
 public:
  // Throws InputError naming a file that cannot be created.
  explicit GroundTruth(const std::filesystem::path& dir);
  // Packet `index` of frame k, rendered into `encoded`, was sent.
  void packet_sent(const ForwardModel& model, uint64_t frame, size_t index, const EncodedFrame& encoded);
  void close();  // logs a failed write

 private:
  TumWriter frames_;
  TumWriter columns_;
};

}  // namespace lidartwin::streamer_detail
