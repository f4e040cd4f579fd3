#pragma once
// Which lidar packets a frame sends for its column window (protocol doc 6.2, 6.4). A pure function
// of the data format; the frame_id they carry is packet/data_format.h's frame_id_of.
#include <cstdint>
#include <vector>

#include "lidartwin/packet/data_format.h"

namespace lidartwin {

// First measurement ids of the packets one frame sends, in send order (rising m; the frame starts
// at m = 0 even when the window wraps, 6.2). A packet is sent iff at least one of its columns lies
// in column_window (6.4): [1,256]@512 -> 17 packets, [370,85]@512 -> 15.
std::vector<int> packets_to_send(const LidarDataFormat& format);

}  // namespace lidartwin
