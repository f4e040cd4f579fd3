#pragma once
// Fault injection at run time (docs/fault-injection.md), below /lidartwin/v1/faults:
// - GET [?since=CURSOR&limit=N]: the plan, the spec that replays it, counts per kind and the log
//   of faults injected (from cursor `since`, at most `limit`, default 1000);
// - PUT or POST with a plan as JSON (the keys of `serve --fault`): replaces the plan whole, or
//   answers 400 naming the key and keeps the old one;
// - DELETE: no faults.
#include <cstdint>

#include "lidartwin/fault/fault_control.h"
#include "lidartwin/http_api/request_handler.h"

namespace lidartwin {

// default_seed: a plan without "seed" gets it (serve's --seed).
ApiResponse fault_endpoint(FaultControl& faults, uint64_t default_seed, const ApiRequest& request);

}  // namespace lidartwin
