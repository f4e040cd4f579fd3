#pragma once
// The fault plan a daemon runs, shared by the streamer (packets, sensor events), the HTTP server
// and the endpoint that changes it at run time; and the log of every fault injected, so that a
// driver's failing run can be lined up with what was done to it.
#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "lidartwin/fault/fault_plan.h"

namespace lidartwin {

class FaultControl {
 public:
  // `sensor_name`: a rig's sensor, named in the log lines ("faults (roof): ...").
  explicit FaultControl(FaultPlan plan = {}, std::string sensor_name = {});
  FaultControl(const FaultControl&) = delete;
  FaultControl& operator=(const FaultControl&) = delete;

  // Any thread. Replaces the plan whole (its sensor events may happen again) and logs the spec
  // that replays it; counts and the event log go on.
  void set(FaultPlan plan);
  FaultPlan plan() const;
  // +1 per set(): readers on hot paths compare it with the one they cached the plan at.
  uint64_t generation() const;

  // One fault injected: counted under `kind` and kept, with `detail`, among the newest
  // kMaxEvents. A log line at debug level (info for the sensor's events).
  void record(std::string_view kind, nlohmann::json detail);
  // The sequence number of the next faultable HTTP request under the current plan.
  uint64_t next_http_request();

  // {"plan", "spec", "generation", "counts", "events" (cursor >= since, at most max_events),
  //  "next_cursor"}: what GET /lidartwin/v1/faults answers.
  nlohmann::json status(uint64_t since, size_t max_events) const;

  static constexpr size_t kMaxEvents = 100'000;

 private:
  const std::string tag_;  // log_tag.h
  mutable std::mutex mutex_;
  FaultPlan plan_;
  std::atomic<uint64_t> generation_{0};
  uint64_t http_requests_ = 0;  // under this plan
  std::map<std::string, uint64_t, std::less<>> counts_;
  std::deque<nlohmann::json> events_;  // the newest kMaxEvents
  uint64_t next_cursor_ = 0;
};

}  // namespace lidartwin
