#include "lidartwin/json/json_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "lidartwin/error.h"

namespace lidartwin::json_reader {

std::string type_name(const nlohmann::json& value) {
  if (value.is_number()) return "a number";
  if (value.is_boolean()) return "a boolean";
  if (value.is_null()) return "null";
  return std::string(value.is_array() || value.is_object() ? "an " : "a ") + value.type_name();
}

std::string describe(const nlohmann::json& value) {
  if (value.is_array()) return "an array of " + std::to_string(value.size());
  if (value.is_object() || value.is_null()) return type_name(value);
  // Replacing invalid UTF-8: a message about a bad string must not itself fail on it (a --fault
  // spec of raw bytes made dump() throw out of the error path; found by the fault_plan fuzzer).
  std::string text = value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  return type_name(value) + " " + text;
}

std::string format_number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", value);
  return buffer;
}

std::string escape_token(std::string_view key) {
  std::string out;
  for (const char c : key) {
    if (c == '~') {
      out += "~0";
    } else if (c == '/') {
      out += "~1";
    } else {
      out += c;
    }
  }
  return out;
}

bool Range::contains(double value) const {
  const bool above = lower_open ? value > lower : value >= lower;
  const bool below = upper_open ? value < upper : value <= upper;
  return std::isfinite(value) && above && below;
}

std::string Range::to_string() const {
  return (lower_open ? "(" : "[") + format_number(lower) + ", " + format_number(upper) + (upper_open ? ")" : "]");
}

void Location::fail(std::string_view what) const { throw InputError(to_string() + ": " + std::string(what)); }

void Location::fail_expected(std::string_view what, const nlohmann::json& got) const {
  fail("must be " + std::string(what) + ", got " + describe(got));
}

double read_number(const nlohmann::json& value, const Location& at, const Range& allowed) {
  if (!value.is_number()) at.fail_expected("a number in " + allowed.to_string(), value);
  const double number = value.get<double>();
  if (!allowed.contains(number)) at.fail("must be in " + allowed.to_string() + ", got " + format_number(number));
  return number;
}

double read_finite(const nlohmann::json& value, const Location& at) {
  if (!value.is_number()) at.fail_expected("a number", value);
  const double number = value.get<double>();
  if (!std::isfinite(number)) at.fail_expected("a finite number", value);
  return number;
}

int64_t read_integer(const nlohmann::json& value, const Location& at, int64_t min, int64_t max) {
  const std::string expected = "an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
  if (value.is_number_unsigned()) {
    const uint64_t number = value.get<uint64_t>();
    if (number <= static_cast<uint64_t>(max) && (min <= 0 || number >= static_cast<uint64_t>(min))) {
      return static_cast<int64_t>(number);
    }
  } else if (value.is_number_integer()) {
    const int64_t number = value.get<int64_t>();
    if (number >= min && number <= max) return number;
  } else if (value.is_number_float()) {
    const double number = value.get<double>();
    if (std::isfinite(number) && number == std::floor(number) && number >= static_cast<double>(min) &&
        number <= static_cast<double>(max)) {
      return static_cast<int64_t>(number);
    }
  }
  at.fail_expected(expected, value);
}

std::string read_string(const nlohmann::json& value, const Location& at) {
  if (!value.is_string()) at.fail_expected("a string", value);
  return value.get<std::string>();
}

bool read_bool(const nlohmann::json& value, const Location& at) {
  if (!value.is_boolean()) at.fail_expected("true or false", value);
  return value.get<bool>();
}

std::vector<double> read_numbers(const nlohmann::json& value, const Location& at, const Range& allowed,
                                 std::optional<size_t> count) {
  const std::string what =
      (count ? std::to_string(*count) + " numbers" : std::string("an array of numbers")) + " in " + allowed.to_string();
  if (!value.is_array()) at.fail_expected(what, value);
  if (count && value.size() != *count) at.fail_expected(what, value);
  std::vector<double> numbers;
  numbers.reserve(value.size());
  for (size_t i = 0; i < value.size(); ++i) numbers.push_back(read_number(value[i], at.child(i), allowed));
  return numbers;
}

ObjectReader::ObjectReader(const nlohmann::json& value, Location at, std::vector<std::string_view> allowed,
                           UnknownKeys unknown, std::string_view owner)
    : object_(value), at_(std::move(at)) {
  if (!value.is_object()) at_.fail_expected("an object", value);
  if (unknown == UnknownKeys::kKeep) return;
  for (const auto& [key, unused] : value.items()) {
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    const std::string what = owner.empty() ? "unknown key" : "unknown key of " + std::string(owner);
    at_.child(key).fail(allowed.empty() ? what + "; none are allowed here"
                                        : fmt::format("{}; allowed keys here: {}", what, fmt::join(allowed, ", ")));
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

}  // namespace lidartwin::json_reader
