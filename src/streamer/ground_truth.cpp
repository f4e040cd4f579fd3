#include "streamer/ground_truth.h"

#include <spdlog/spdlog.h>

#include "lidartwin/error.h"

namespace lidartwin::streamer_detail {

GroundTruth::GroundTruth(const std::filesystem::path& dir)
    : frames_(dir / "poses.tum"), columns_(dir / "column_poses.tum") {}

void GroundTruth::packet_sent(const ForwardModel& model, uint64_t frame, size_t index, const EncodedFrame& encoded) {
  const SensorClock& clock = model.clock();
  if (index == 0) {
    const double pose_time_s = clock.column_pose_time_s(frame, 0);
    if (model.poses().span().contains(pose_time_s)) {
      frames_.write(static_cast<double>(clock.column_timestamp_ns(frame, 0)) * 1e-9, model.poses().at(pose_time_s));
    }
  }
  const int first = model.packet_columns()[index];
  for (int m = first; m < first + model.format().columns_per_packet; ++m) {
    const auto column = static_cast<size_t>(m);
    if (!encoded.columns.observed[column]) continue;
    columns_.write(static_cast<double>(encoded.scan.timestamp_ns[column]) * 1e-9, encoded.columns.poses[column]);
  }
}

void GroundTruth::close() {
  try {
    frames_.close();
    columns_.close();
  } catch (const InputError& e) {
    spdlog::error("streamer: --record ground truth: {}", e.what());
  }
}

}  // namespace lidartwin::streamer_detail
