// Effect parameter reading and checking; see parameters.h.
#include "effects/parameters.h"

#include <vector>

#include "lidartwin/json/json_reader.h"

namespace lidartwin::effects_detail {

std::string format_number(double value) { return json_reader::format_number(value); }

std::string format_range(double lower, double upper) { return json_reader::Range{lower, upper}.to_string(); }

Location fitted(std::string_view effect) { return {std::string(effect), ""}; }

void check_number(double value, const Location& at, Bounds bounds) {
  if (!(value >= bounds.lower && value <= bounds.upper)) {  // also rejects NaN
    at.fail("must be in " + format_range(bounds.lower, bounds.upper) + ", got " + format_number(value));
  }
}

double read_number(const nlohmann::json& value, const Location& at, Bounds bounds) {
  if (!value.is_number()) at.fail_expected("a number in " + format_range(bounds.lower, bounds.upper), value);
  const double number = value.get<double>();
  check_number(number, at, bounds);
  return number;
}

void check_keys(const nlohmann::json& params, const Location& at, std::string_view effect,
                std::span<const std::string_view> allowed) {
  std::vector<std::string_view> keys{"name"};
  keys.insert(keys.end(), allowed.begin(), allowed.end());
  json_reader::ObjectReader(params, at, keys, json_reader::UnknownKeys::kReject, effect);
}

void check_count(size_t got, size_t expected, std::string_view effect) {
  if (got != expected) {
    fitted(effect).fail("expected " + std::to_string(expected) + " parameter values, got " + std::to_string(got));
  }
}

}  // namespace lidartwin::effects_detail
