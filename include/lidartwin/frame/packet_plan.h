#pragma once
// Which lidar packets a frame sends for its column window, and the frame_id they carry (protocol
// doc 4.3, 6.2, 6.4). Pure functions of the data format.
#include <cstdint>
#include <vector>

#include "lidartwin/packet/data_format.h"

namespace lidartwin {

// First measurement ids of the packets one frame sends, in send order (rising m; the frame starts
// at m = 0 even when the window wraps, 6.2). A packet is sent iff at least one of its columns lies
// in column_window (6.4): [1,256]@512 -> 17 packets, [370,85]@512 -> 15.
std::vector<int> packets_to_send(const LidarDataFormat& format);

// frame_id of the n-th frame of a stream: +1 per revolution, wrapping at 2^16 (STANDARD, LEGACY)
// or 2^32 (FUSA header, 4.3).
bool uses_fusa_header(const LidarDataFormat& format);
uint32_t frame_id_of(uint64_t frame_index, const LidarDataFormat& format);

}  // namespace lidartwin
