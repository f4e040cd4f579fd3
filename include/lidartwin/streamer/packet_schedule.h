#pragma once
// The column clock as pure functions: which lidar packets a frame sends for its column window, when
// each one is due, and which frame_id it carries (protocol doc 1 items 11-12, 6.1, 6.2, 6.4). No
// sockets, no clocks: the streamer adds a start time and sends.
#include <array>
#include <cstdint>
#include <vector>

#include "lidartwin/packet/data_format.h"

namespace lidartwin {

// Time of columns within a stream of frames, in integer nanoseconds from the stream's start.
// Frame n starts at n * 1e9 / fps (exact for 5, 10 and 20 Hz); column m of a frame is observed
// m * 1e9 / (W * fps) after its frame start (6.1), rounded down, so column times never drift.
struct ColumnClock {
  int columns_per_frame = 1024;
  int fps = 10;

  uint64_t frame_period_ns() const;
  uint64_t column_offset_ns(int measurement_id) const;
  uint64_t frame_start_ns(uint64_t frame_index) const;
  uint64_t column_time_ns(uint64_t frame_index, int measurement_id) const;
};

// First measurement ids of the packets one frame sends, in send order (rising m; the frame starts
// at m = 0 even when the window wraps, 6.2). A packet is sent iff at least one of its columns lies
// in column_window (6.4): [1,256]@512 -> 17 packets, [370,85]@512 -> 15.
std::vector<int> packets_to_send(const LidarDataFormat& format);

// A packet is due when its last column has been observed (protocol doc 1 item 12): the deadline of
// the packet starting at first_column, from the start of its frame. Packets of a full window are
// therefore spaced columns_per_packet column periods apart, never sent as a burst.
uint64_t packet_deadline_offset_ns(const ColumnClock& clock, int first_column, int columns_per_packet);

// frame_id of the n-th frame of a stream: +1 per revolution, wrapping at 2^16 (STANDARD, LEGACY)
// or 2^32 (FUSA header, 4.3).
bool uses_fusa_header(const LidarDataFormat& format);
uint32_t frame_id_of(uint64_t frame_index, const LidarDataFormat& format);

// IMU packets go out at 100 Hz (5.1): the k-th one is due k * 10 ms after the stream's start.
inline constexpr uint64_t kImuPeriodNs = 10'000'000;

}  // namespace lidartwin
