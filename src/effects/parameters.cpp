// Effect parameter reading and checking; see parameters.h.
#include "effects/parameters.h"

#include <vector>

#include "lidartwin/json/json_reader.h"

namespace lidartwin::effects_detail {

std::string json_path(std::string_view source, std::string_view token) {
  const bool has_pointer = source.find(": /") != std::string_view::npos;
  return std::string(source) + (has_pointer ? "/" : ": /") + json_reader::escape_token(token);
}

// "file: /effects/2" -> {"file", "/effects/2"}; a source without a pointer is the whole document.
json_reader::Location location_of(std::string_view where) {
  const size_t split = where.find(": /");
  if (split == std::string_view::npos) return {std::string(where), ""};
  return {std::string(where.substr(0, split)), std::string(where.substr(split + 2))};
}

void fail(std::string_view where, std::string_view what) { location_of(where).fail(what); }

std::string format_number(double value) { return json_reader::format_number(value); }

std::string format_range(double lower, double upper) { return json_reader::Range{lower, upper}.to_string(); }

void check_number(double value, std::string_view where, Bounds bounds) {
  if (!(value >= bounds.lower && value <= bounds.upper)) {  // also rejects NaN
    fail(where, "must be in " + format_range(bounds.lower, bounds.upper) + ", got " + format_number(value));
  }
}

double read_number(const nlohmann::json& value, std::string_view where, Bounds bounds) {
  // Bounds may be infinite (an unbounded parameter), which json_reader::Range does not take.
  if (!value.is_number())
    location_of(where).fail_expected("a number in " + format_range(bounds.lower, bounds.upper), value);
  const double number = value.get<double>();
  check_number(number, where, bounds);
  return number;
}

void check_keys(const nlohmann::json& params, std::string_view source, std::string_view effect,
                std::span<const std::string_view> allowed) {
  std::vector<std::string_view> keys{"name"};
  keys.insert(keys.end(), allowed.begin(), allowed.end());
  json_reader::ObjectReader(params, location_of(source), keys, json_reader::UnknownKeys::kReject, effect);
}

void check_count(size_t got, size_t expected, std::string_view effect) {
  if (got != expected) {
    fail(effect, "expected " + std::to_string(expected) + " parameter values, got " + std::to_string(got));
  }
}

}  // namespace lidartwin::effects_detail
