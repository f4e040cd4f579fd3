// libFuzzer: a fault plan as `serve --fault SPEC` and PUT /lidartwin/v1/faults take it (text, or
// JSON when it starts with '{'): parsed or refused with an InputError; a plan that parses writes a
// spec and JSON that parse back to it, and its schedule can be drawn. Seeds: tests/fuzz/seeds/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include <nlohmann/json.hpp>

#include "lidartwin/error.h"
#include "lidartwin/fault/fault_plan.h"
#include "lidartwin/fault/fault_schedule.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  lidartwin::FaultPlan plan;
  try {
    if (!text.empty() && text.front() == '{') {
      const nlohmann::json document = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
      if (document.is_discarded()) return 0;
      plan = lidartwin::fault_plan_from_json(document, "fuzz input", 1);
    } else {
      plan = lidartwin::fault_plan_from_spec(text, 1);
    }
  } catch (const lidartwin::InputError&) {
    return 0;
  }
  // What the daemon logs must replay the plan it runs.
  if (!(lidartwin::fault_plan_from_spec(lidartwin::to_spec(plan), 0) == plan)) std::abort();
  if (!(lidartwin::fault_plan_from_json(lidartwin::to_json(plan), "to_json", 0) == plan)) std::abort();
  for (uint64_t i = 0; i < 64; ++i) {
    const lidartwin::DatagramFate fate = lidartwin::datagram_fate(plan, lidartwin::FaultStream::kLidar, 0, i, 1500);
    if (fate.truncated_to >= 1500 || fate.delay_ns < 0) std::abort();
    (void)lidartwin::frame_jumps(plan, 0, i);
    (void)lidartwin::http_fate(plan, i);
  }
  return 0;
}
