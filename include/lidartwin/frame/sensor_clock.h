#pragma once
// The sensor's clock, the one place that says when things happen (protocol doc 1 items 11-12, 5.1,
// 6.1, 6.3): when column m of frame k is observed, what timestamp it carries, when its packet is
// due, where the pose source's time stands then, and the same for the IMU's samples. No sockets,
// no host clocks: the streamer maps these times onto the steady clock, `record` writes them.
#include <cstdint>

namespace lidartwin {

// IMU packets go out at 100 Hz (5.1): sample i is read i * 10 ms after the stream starts.
inline constexpr uint64_t kImuPeriodNs = 10'000'000;

struct SensorClock {
  int columns_per_frame = 1024;
  int fps = 10;
  // The timestamp (6.3) of frame 0's column 0, in the stream's timestamp_mode.
  uint64_t origin_ns = 0;
  // The pose source's time at frame 0's column 0, in seconds.
  double pose_origin_s = 0.0;

  // Frame k starts k * 1e9 / fps ns after the origin (exact for 5, 10 and 20 Hz); column m is
  // observed m * 1e9 / (W * fps) after its frame starts (6.1), rounded down, so times never drift.
  uint64_t frame_period_ns() const;
  uint64_t frame_start_ns(uint64_t frame) const;        // from the origin
  uint64_t column_offset_ns(int measurement_id) const;  // from the frame's start
  uint64_t column_timestamp_ns(uint64_t frame, int measurement_id) const;
  // A packet is due when its last column has been observed (protocol doc 1 item 12), so packets of
  // a full window are spaced columns_per_packet column periods apart, never sent as a burst.
  uint64_t packet_due_offset_ns(int first_column, int columns_per_packet) const;  // from the frame's start
  uint64_t packet_timestamp_ns(uint64_t frame, int first_column, int columns_per_packet) const;
  // The pose source's time when column m of frame k is observed. Seconds in double: the frame's
  // start (pose_origin_s + k / fps) plus the column's offset m / (W * fps).
  double column_pose_time_s(uint64_t frame, int measurement_id) const;

  uint64_t imu_timestamp_ns(uint64_t sample) const { return origin_ns + sample * kImuPeriodNs; }
  double imu_pose_time_s(uint64_t sample) const { return pose_origin_s + static_cast<double>(sample) * 0.01; }
};

}  // namespace lidartwin
