// The fates of datagrams, frames and requests under a FaultPlan (fault_schedule.h).
#include "lidartwin/fault/fault_schedule.h"

#include <algorithm>

#include "lidartwin/random/counter_rng.h"

namespace lidartwin {
namespace {

// Independent draws per (what they decide, stream, session, sequence).
enum class Draw : uint64_t { kLossStart = 1, kFate, kTruncateLength, kJitter, kFrameJump, kHttp };

double uniform(const FaultPlan& plan, Draw draw, FaultStream stream, uint64_t session, uint64_t sequence) {
  using rng_detail::mix64;
  uint64_t bits = mix64(plan.seed ^ 0x6661756c74ull);  // "fault": not the noise's keys
  bits = mix64(bits ^ static_cast<uint64_t>(draw));
  bits = mix64(bits ^ static_cast<uint64_t>(stream));
  bits = mix64(bits ^ session);
  bits = mix64(bits ^ sequence);
  return rng_detail::unit(bits);
}

bool loss_starts(const FaultPlan& plan, FaultStream stream, uint64_t session, uint64_t sequence) {
  return uniform(plan, Draw::kLossStart, stream, session, sequence) < plan.loss / plan.loss_burst;
}

}  // namespace

DatagramFate datagram_fate(const FaultPlan& plan, FaultStream stream, uint64_t session, uint64_t sequence,
                           size_t size) {
  DatagramFate fate;
  if (plan.loss > 0) {
    const uint64_t first =
        sequence >= static_cast<uint64_t>(plan.loss_burst - 1) ? sequence - (plan.loss_burst - 1) : 0;
    for (uint64_t start = first; start <= sequence && !fate.lost; ++start) {
      fate.lost = loss_starts(plan, stream, session, start);
    }
    if (fate.lost) return fate;
  }
  // One draw picks at most one of the fates that change what arrives: their rates add up to <= 1
  // (fault_plan_from_json checks), and a datagram both lost and duplicated would mean nothing.
  double u = uniform(plan, Draw::kFate, stream, session, sequence);
  const auto take = [&u](double rate) {
    if (u < rate) return true;
    u -= rate;
    return false;
  };
  if (take(plan.reorder)) {
    fate.reordered = true;
  } else if (take(plan.duplicate)) {
    fate.duplicated = true;
  } else if (take(plan.truncate) && size > 1) {
    // Anything from 1 byte to one short of whole.
    const double length = uniform(plan, Draw::kTruncateLength, stream, session, sequence);
    fate.truncated_to =
        std::clamp<size_t>(1 + static_cast<size_t>(length * static_cast<double>(size - 1)), 1, size - 1);
  } else if (stream == FaultStream::kLidar && take(plan.bad_crc)) {
    fate.bad_crc = true;
  }
  if (plan.delay_ms > 0 || plan.jitter_ms > 0) {
    const double jitter = plan.jitter_ms * uniform(plan, Draw::kJitter, stream, session, sequence);
    fate.delay_ns = static_cast<int64_t>((plan.delay_ms + jitter) * 1e6);
  }
  return fate;
}

bool frame_jumps(const FaultPlan& plan, uint64_t session, uint64_t frame) {
  return plan.frame_jump > 0 && uniform(plan, Draw::kFrameJump, FaultStream::kFrames, session, frame) < plan.frame_jump;
}

HttpFate http_fate(const FaultPlan& plan, uint64_t request) {
  HttpFate fate;
  fate.fail = plan.http_500 > 0 && uniform(plan, Draw::kHttp, FaultStream::kHttp, 0, request) < plan.http_500;
  fate.delay_ns = static_cast<int64_t>(plan.http_delay_ms * 1e6);
  return fate;
}

}  // namespace lidartwin
