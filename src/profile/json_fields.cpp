// JSON reading helpers for profiles; see json_fields.h.
#include "profile/json_fields.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <fmt/ranges.h>

#include "lidartwin/error.h"

namespace lidartwin::profile_detail {
namespace {

std::string format_number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", value);
  return buffer;
}

}  // namespace

bool Range::contains(double value) const {
  const bool above = lower_open ? value > lower : value >= lower;
  const bool below = upper_open ? value < upper : value <= upper;
  return std::isfinite(value) && above && below;
}

std::string Range::to_string() const {
  return (lower_open ? "(" : "[") + format_number(lower) + ", " + format_number(upper) + (upper_open ? ")" : "]");
}

void Location::fail(std::string_view what) const {
  throw InputError(std::string(source) + ": " + (pointer.empty() ? "/" : pointer) + ": " + std::string(what));
}

std::string type_name(const nlohmann::json& value) {
  if (value.is_number()) return "a number";
  if (value.is_boolean()) return "a boolean";
  return std::string(value.is_array() || value.is_object() ? "an " : "a ") + value.type_name();
}

double read_number(const nlohmann::json& value, const Location& at, const Range& allowed) {
  if (!value.is_number()) at.fail("must be a number in " + allowed.to_string() + ", got " + type_name(value));
  const double number = value.get<double>();
  if (!allowed.contains(number)) at.fail("must be in " + allowed.to_string() + ", got " + value.dump());
  return number;
}

std::string read_string(const nlohmann::json& value, const Location& at) {
  if (!value.is_string()) at.fail("must be a string, got " + type_name(value));
  return value.get<std::string>();
}

bool read_bool(const nlohmann::json& value, const Location& at) {
  if (!value.is_boolean()) at.fail("must be true or false, got " + type_name(value));
  return value.get<bool>();
}

std::vector<double> read_numbers(const nlohmann::json& value, const Location& at, const Range& allowed) {
  if (!value.is_array()) at.fail("must be an array of numbers in " + allowed.to_string() + ", got " + type_name(value));
  std::vector<double> numbers;
  numbers.reserve(value.size());
  for (size_t i = 0; i < value.size(); ++i) numbers.push_back(read_number(value[i], at.child(i), allowed));
  return numbers;
}

ObjectReader::ObjectReader(const nlohmann::json& value, Location at, std::vector<std::string_view> allowed)
    : object_(value), at_(std::move(at)) {
  if (!value.is_object()) at_.fail("must be an object, got " + type_name(value));
  for (const auto& [key, unused] : value.items()) {
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      at_.child(key).fail(fmt::format("unknown key; allowed keys here: {}", fmt::join(allowed, ", ")));
    }
  }
}

const nlohmann::json* ObjectReader::find(std::string_view key) const {
  const auto it = object_.find(key);
  return it == object_.end() ? nullptr : &*it;
}

const nlohmann::json& ObjectReader::at(std::string_view key, std::string_view what) const {
  const nlohmann::json* value = find(key);
  if (value == nullptr) at_.child(key).fail("missing (expected " + std::string(what) + ")");
  return *value;
}

}  // namespace lidartwin::profile_detail
