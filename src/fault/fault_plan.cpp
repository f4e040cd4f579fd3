// FaultPlan from a --fault SPEC or JSON, through the one JSON reader (json_reader.h), and back.
#include "lidartwin/fault/fault_plan.h"

#include <charconv>
#include <cmath>

#include <fmt/format.h>

#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin {
namespace {

using nlohmann::json;
namespace jr = json_reader;

constexpr jr::Range kFraction{0.0, 1.0};
constexpr jr::Range kMilliseconds{0.0, 60'000.0};     // a minute: longer is an outage, not a delay
constexpr jr::Range kAtSeconds{0.0, 86'400.0};        // within a day of streaming
constexpr jr::Range kForSeconds{0.0, 3'600.0, true};  // (0, an hour]

// Keys in the order to_spec writes them.
constexpr std::string_view kKeys[] = {"seed",          "loss",     "loss_burst",   "reorder",     "duplicate",
                                      "truncate",      "bad_crc",  "delay_ms",     "jitter_ms",   "frame_jump",
                                      "frame_jump_by", "reset_at", "standby_at",   "standby_for", "error_at",
                                      "error_for",     "http_500", "http_delay_ms"};

// A spec value as JSON: a number when the whole text is one (so the reader checks its range), the
// text otherwise (so the reader says "must be a number, got a string ...").
json spec_value(std::string_view text) {
  double number = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), number);
  if (error == std::errc() && end == text.data() + text.size() && std::isfinite(number)) {
    uint64_t integer = 0;
    const auto [int_end, int_error] = std::from_chars(text.data(), text.data() + text.size(), integer);
    if (int_error == std::errc() && int_end == text.data() + text.size()) return integer;
    return number;
  }
  return std::string(text);
}

// The spec as a message can show it: bytes outside printable ASCII as \xHH (a NUL would end the
// message, and raw bytes are no text).
std::string printable(std::string_view text) {
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte >= 0x20 && byte < 0x7F) {
      out += c;
    } else {
      out += fmt::format("\\x{:02X}", byte);
    }
  }
  return out;
}

// The shortest text that reads back as the same double ("0.01", not "0.01000000000000000021").
std::string shortest(double value) {
  char buffer[32];
  const auto [end, error] = std::to_chars(buffer, buffer + sizeof buffer, value);
  return error == std::errc() ? std::string(buffer, end) : jr::format_number(value);
}

std::string_view trimmed(std::string_view text) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  return text;
}

}  // namespace

bool FaultPlan::has_packet_faults() const {
  return loss > 0 || reorder > 0 || duplicate > 0 || truncate > 0 || bad_crc > 0 || delay_ms > 0 || jitter_ms > 0 ||
         frame_jump > 0;
}

bool FaultPlan::has_sensor_events() const { return reset_at || standby_at || error_at; }

bool FaultPlan::empty() const {
  return !has_packet_faults() && !has_sensor_events() && http_500 <= 0 && http_delay_ms <= 0;
}

FaultPlan fault_plan_from_json(const json& document, const std::string& source, uint64_t default_seed) {
  const jr::ObjectReader object(document, {source, ""},
                                std::vector<std::string_view>(std::begin(kKeys), std::end(kKeys)),
                                jr::UnknownKeys::kReject, "a fault plan");
  FaultPlan plan;
  plan.seed = default_seed;
  const auto number = [&](std::string_view key, double& out, const jr::Range& range) {
    if (const json* value = object.find(key)) out = jr::read_number(*value, object.child(key), range);
  };
  const auto optional = [&](std::string_view key, std::optional<double>& out, const jr::Range& range) {
    if (const json* value = object.find(key)) out = jr::read_number(*value, object.child(key), range);
  };
  const auto integer = [&](std::string_view key, int& out, int64_t min, int64_t max) {
    if (const json* value = object.find(key))
      out = static_cast<int>(jr::read_integer(*value, object.child(key), min, max));
  };
  if (const json* value = object.find("seed")) {
    plan.seed = static_cast<uint64_t>(jr::read_integer(*value, object.child("seed"), 0, INT64_MAX));
  }
  number("loss", plan.loss, kFraction);
  integer("loss_burst", plan.loss_burst, 1, 1000);
  number("reorder", plan.reorder, kFraction);
  number("duplicate", plan.duplicate, kFraction);
  number("truncate", plan.truncate, kFraction);
  number("bad_crc", plan.bad_crc, kFraction);
  number("delay_ms", plan.delay_ms, kMilliseconds);
  number("jitter_ms", plan.jitter_ms, kMilliseconds);
  number("frame_jump", plan.frame_jump, kFraction);
  integer("frame_jump_by", plan.frame_jump_by, 1, 65535);
  optional("reset_at", plan.reset_at, kAtSeconds);
  optional("standby_at", plan.standby_at, kAtSeconds);
  number("standby_for", plan.standby_for, kForSeconds);
  optional("error_at", plan.error_at, kAtSeconds);
  number("error_for", plan.error_for, kForSeconds);
  number("http_500", plan.http_500, kFraction);
  number("http_delay_ms", plan.http_delay_ms, kMilliseconds);
  // Each datagram meets at most one of these fates that change what arrives (see datagram_fate).
  if (plan.loss + plan.reorder + plan.duplicate + plan.truncate + plan.bad_crc > 1.0) {
    object.location().fail(
        "loss + reorder + duplicate + truncate + bad_crc must be at most 1 (each datagram meets "
        "at most one of them)");
  }
  return plan;
}

FaultPlan fault_plan_from_spec(std::string_view spec, uint64_t default_seed) {
  const std::string source = "--fault \"" + printable(spec) + "\"";
  json document = json::object();
  std::string_view rest = spec;
  while (!trimmed(rest).empty()) {
    const size_t comma = rest.find(',');
    const std::string_view item = trimmed(rest.substr(0, comma));
    rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
    const size_t equals = item.find('=');
    if (item.empty() || equals == std::string_view::npos || trimmed(item.substr(0, equals)).empty()) {
      throw InputError(source + ": \"" + std::string(item) + "\" is not KEY=VALUE (e.g. loss=0.01,reset_at=5)");
    }
    const std::string key(trimmed(item.substr(0, equals)));
    if (document.contains(key)) throw InputError(source + ": " + key + " is given twice");
    document[key] = spec_value(trimmed(item.substr(equals + 1)));
  }
  return fault_plan_from_json(document, source, default_seed);
}

// Every key that differs from the default, so that the plan reads back equal (a frame_jump_by
// without frame_jump does nothing, but a replay should not depend on knowing that).
json to_json(const FaultPlan& plan) {
  json out{{"seed", plan.seed}};
  const FaultPlan none;
  const auto put = [&](const char* key, auto value, auto unset) {
    if (value != unset) out[key] = value;
  };
  put("loss", plan.loss, none.loss);
  put("loss_burst", plan.loss_burst, none.loss_burst);
  put("reorder", plan.reorder, none.reorder);
  put("duplicate", plan.duplicate, none.duplicate);
  put("truncate", plan.truncate, none.truncate);
  put("bad_crc", plan.bad_crc, none.bad_crc);
  put("delay_ms", plan.delay_ms, none.delay_ms);
  put("jitter_ms", plan.jitter_ms, none.jitter_ms);
  put("frame_jump", plan.frame_jump, none.frame_jump);
  put("frame_jump_by", plan.frame_jump_by, none.frame_jump_by);
  if (plan.reset_at) out["reset_at"] = *plan.reset_at;
  if (plan.standby_at) out["standby_at"] = *plan.standby_at;
  put("standby_for", plan.standby_for, none.standby_for);
  if (plan.error_at) out["error_at"] = *plan.error_at;
  put("error_for", plan.error_for, none.error_for);
  put("http_500", plan.http_500, none.http_500);
  put("http_delay_ms", plan.http_delay_ms, none.http_delay_ms);
  return out;
}

std::string to_spec(const FaultPlan& plan) {
  const json document = to_json(plan);
  std::string spec;
  for (std::string_view key : kKeys) {
    const auto it = document.find(key);
    if (it == document.end()) continue;
    if (!spec.empty()) spec += ',';
    spec += fmt::format("{}={}", key, it->is_number_float() ? shortest(it->get<double>()) : it->dump());
  }
  return spec;
}

}  // namespace lidartwin
