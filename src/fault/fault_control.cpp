// The shared fault plan and the log of what it did (fault_control.h).
#include "lidartwin/fault/fault_control.h"

#include <algorithm>
#include <chrono>

#include <spdlog/spdlog.h>

#include "lidartwin/log_tag.h"

namespace lidartwin {

using nlohmann::json;

namespace {
int64_t monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

FaultControl::FaultControl(FaultPlan plan, std::string sensor_name) : tag_(log_tag(sensor_name)) {
  set(std::move(plan));
}

void FaultControl::set(FaultPlan plan) {
  if (plan.empty()) {
    spdlog::info("faults{}: none", tag_);
  } else {
    spdlog::info("faults{}: {} (replay with --fault \"{}\")", tag_, to_json(plan).dump(), to_spec(plan));
  }
  std::lock_guard lock(mutex_);
  plan_ = std::move(plan);
  http_requests_ = 0;
  generation_.fetch_add(1, std::memory_order_release);
}

FaultPlan FaultControl::plan() const {
  std::lock_guard lock(mutex_);
  return plan_;
}

uint64_t FaultControl::generation() const { return generation_.load(std::memory_order_acquire); }

void FaultControl::record(std::string_view kind, json detail) {
  const bool sensor_event = kind == "reset" || kind == "standby" || kind == "error" || kind == "recovered";
  if (sensor_event) {
    spdlog::warn("faults{}: {} {}", tag_, kind, detail.dump());
  } else if (spdlog::should_log(spdlog::level::debug)) {  // packet faults: not printed unless asked for
    spdlog::debug("faults{}: {} {}", tag_, kind, detail.dump());
  }
  std::lock_guard lock(mutex_);
  ++counts_[std::string(kind)];
  detail["kind"] = kind;
  detail["cursor"] = next_cursor_++;
  detail["monotonic_ns"] = monotonic_ns();
  events_.push_back(std::move(detail));
  if (events_.size() > kMaxEvents) events_.pop_front();
}

uint64_t FaultControl::next_http_request() {
  std::lock_guard lock(mutex_);
  return http_requests_++;
}

json FaultControl::status(uint64_t since, size_t max_events) const {
  std::lock_guard lock(mutex_);
  // Cursors are consecutive: the oldest kept is next_cursor_ - events_.size().
  const uint64_t oldest = next_cursor_ - events_.size();
  json events = json::array();
  for (uint64_t cursor = std::max(since, oldest); cursor < next_cursor_ && events.size() < max_events; ++cursor) {
    events.push_back(events_[static_cast<size_t>(cursor - oldest)]);
  }
  json counts = json::object();
  for (const auto& [kind, count] : counts_) counts[kind] = count;
  return {{"plan", to_json(plan_)},
          {"spec", to_spec(plan_)},
          {"generation", generation_.load()},
          {"counts", counts},
          {"events", events},
          {"next_cursor", events.empty() ? next_cursor_ : events.back()["cursor"].get<uint64_t>() + 1}};
}

}  // namespace lidartwin
