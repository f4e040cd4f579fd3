// Effect parameter reading and checking; see parameters.h.
#include "effects/parameters.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <fmt/ranges.h>

#include "lidartwin/error.h"

namespace lidartwin::effects_detail {
namespace {

// A JSON pointer token escapes '~' and '/' (RFC 6901), so an unknown key prints unambiguously.
std::string escape_token(std::string_view token) {
  std::string out;
  for (const char c : token) {
    switch (c) {
      case '~':
        out += "~0";
        break;
      case '/':
        out += "~1";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string type_name(const nlohmann::json& value) {
  if (value.is_number()) return "a number";
  if (value.is_boolean()) return "a boolean";
  return std::string(value.is_array() || value.is_object() ? "an " : "a ") + value.type_name();
}

}  // namespace

std::string json_path(std::string_view source, std::string_view token) {
  const bool has_pointer = source.find(": /") != std::string_view::npos;
  return std::string(source) + (has_pointer ? "/" : ": /") + escape_token(token);
}

void fail(std::string_view where, std::string_view what) {
  throw InputError(std::string(where) + ": " + std::string(what));
}

std::string format_number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", value);
  return buffer;
}

std::string format_range(double lower, double upper) {
  return "[" + format_number(lower) + ", " + format_number(upper) + "]";
}

void check_number(double value, std::string_view where, Bounds bounds) {
  if (!(value >= bounds.lower && value <= bounds.upper)) {  // also rejects NaN
    fail(where, "must be in " + format_range(bounds.lower, bounds.upper) + ", got " + format_number(value));
  }
}

double read_number(const nlohmann::json& value, std::string_view where, Bounds bounds) {
  if (!value.is_number()) {
    fail(where, "must be a number in " + format_range(bounds.lower, bounds.upper) + ", got " + type_name(value) + " " +
                    value.dump());
  }
  const double number = value.get<double>();
  check_number(number, where, bounds);
  return number;
}

void check_keys(const nlohmann::json& params, std::string_view source, std::string_view effect,
                std::span<const std::string_view> allowed) {
  if (!params.is_object()) fail(source, "must be an object, got " + type_name(params));
  for (const auto& [key, unused] : params.items()) {
    if (key == "name" || std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    const std::string choices =
        allowed.empty() ? "it takes none" : fmt::format("allowed: {}", fmt::join(allowed, ", "));
    fail(json_path(source, key), "unknown parameter of " + std::string(effect) + "; " + choices);
  }
}

void check_count(size_t got, size_t expected, std::string_view effect) {
  if (got != expected) {
    fail(effect, "expected " + std::to_string(expected) + " parameter values, got " + std::to_string(got));
  }
}

}  // namespace lidartwin::effects_detail
