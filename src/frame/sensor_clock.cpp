#include "lidartwin/frame/sensor_clock.h"

#include <cassert>

namespace lidartwin {

namespace {
constexpr uint64_t kNsPerSecond = 1'000'000'000;
}  // namespace

uint64_t SensorClock::frame_period_ns() const { return kNsPerSecond / static_cast<uint64_t>(fps); }

uint64_t SensorClock::frame_start_ns(uint64_t frame) const { return frame * frame_period_ns(); }

uint64_t SensorClock::column_offset_ns(int measurement_id) const {
  assert(measurement_id >= 0 && measurement_id <= columns_per_frame);
  const auto columns_per_second = static_cast<uint64_t>(columns_per_frame) * static_cast<uint64_t>(fps);
  return static_cast<uint64_t>(measurement_id) * kNsPerSecond / columns_per_second;
}

uint64_t SensorClock::column_timestamp_ns(uint64_t frame, int measurement_id) const {
  return origin_ns + frame_start_ns(frame) + column_offset_ns(measurement_id);
}

uint64_t SensorClock::packet_due_offset_ns(int first_column, int columns_per_packet) const {
  return column_offset_ns(first_column + columns_per_packet - 1);
}

uint64_t SensorClock::packet_timestamp_ns(uint64_t frame, int first_column, int columns_per_packet) const {
  return origin_ns + frame_start_ns(frame) + packet_due_offset_ns(first_column, columns_per_packet);
}

double SensorClock::column_pose_time_s(uint64_t frame, int measurement_id) const {
  const double frame_start_s = pose_origin_s + static_cast<double>(frame) / fps;
  return frame_start_s + measurement_id / (static_cast<double>(columns_per_frame) * fps);
}

}  // namespace lidartwin
