#pragma once
// What a FaultPlan does to one datagram, one frame or one HTTP request: pure functions of
// (seed, stream, session, sequence number), drawn from the counter-based generator, so a plan
// replays exactly and the tests can state what a client must see.
#include <cstddef>
#include <cstdint>

#include "lidartwin/fault/fault_plan.h"

namespace lidartwin {

enum class FaultStream : uint64_t { kLidar = 1, kImu = 2, kHttp = 3, kFrames = 4 };

struct DatagramFate {
  bool lost = false;
  bool reordered = false;   // held back and sent after the next datagram of its stream
  bool duplicated = false;  // sent twice
  size_t truncated_to = 0;  // > 0: only this many bytes are sent
  bool bad_crc = false;     // its CRC footer is flipped (lidar packets with a CRC)
  int64_t delay_ns = 0;     // sent this much after it was due
};

// Datagram `sequence` of `stream` in streaming session `session` (each reinit or reset starts one),
// whose size is `size` bytes. A loss burst that starts at datagram s takes s .. s + loss_burst - 1,
// so whether a datagram is lost depends on the draws of the loss_burst before it, not on history.
DatagramFate datagram_fate(const FaultPlan& plan, FaultStream stream, uint64_t session, uint64_t sequence, size_t size);
// Whether frame_id jumps ahead by plan.frame_jump_by at frame `frame` of `session` (and stays so).
bool frame_jumps(const FaultPlan& plan, uint64_t session, uint64_t frame);

struct HttpFate {
  bool fail = false;  // answered 500
  int64_t delay_ns = 0;
};
// The `request`-th request below /api/v1/ since the plan took effect.
HttpFate http_fate(const FaultPlan& plan, uint64_t request);

}  // namespace lidartwin
