#pragma once
// Reading JSON at the profile boundary. Every failure names the file, the JSON pointer of the bad
// element and what was allowed (STYLE.md "Errors at the boundary"); an unknown key is an error, as
// in pbrt's ParameterDictionary::ReportUnused, so a misspelt key never silently keeps a default.
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace lidartwin::profile_detail {

// A closed or open numeric interval, printed as "[0, 90]" or "(0, 1000]".
struct Range {
  double lower;
  double upper;
  bool lower_open = false;
  bool upper_open = false;
  bool contains(double value) const;
  std::string to_string() const;
};

// Where we are: the file (as the user named it) and a JSON pointer inside it.
struct Location {
  std::string_view source;
  std::string pointer;  // "" for the document, "/beam_intrinsics/beam_altitude_angles/3"
  Location child(std::string_view key) const { return {source, pointer + "/" + std::string(key)}; }
  Location child(size_t index) const { return child(std::to_string(index)); }
  [[noreturn]] void fail(std::string_view what) const;
};

// "a number", "a string", ... for messages.
std::string type_name(const nlohmann::json& value);

double read_number(const nlohmann::json& value, const Location& at, const Range& allowed);
std::string read_string(const nlohmann::json& value, const Location& at);
bool read_bool(const nlohmann::json& value, const Location& at);
std::vector<double> read_numbers(const nlohmann::json& value, const Location& at, const Range& allowed);

// One JSON object whose keys must all be among `allowed` (checked on construction).
class ObjectReader {
 public:
  ObjectReader(const nlohmann::json& value, Location at, std::vector<std::string_view> allowed);
  // nullptr if absent.
  const nlohmann::json* find(std::string_view key) const;
  // Throws "missing (expected <what>)" if absent.
  const nlohmann::json& at(std::string_view key, std::string_view what) const;
  const Location& location() const { return at_; }

 private:
  const nlohmann::json& object_;
  Location at_;
};

}  // namespace lidartwin::profile_detail
