#pragma once
// Reading JSON input (profiles, effect parameters, metadata, sensor configs) with one vocabulary:
// every value is read together with where it sits, the input's name and a JSON pointer inside it,
// and every failure is an InputError "<source>: <pointer>: must be <what>, got <what was there>"
// (STYLE.md "Errors at the boundary"). Unknown keys are errors unless a reader chooses to keep them
// (a newer firmware's metadata, a sensor config), and then it says so where it is built.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace lidartwin::json_reader {

// "a number", "a string", "an array", ... for messages.
std::string type_name(const nlohmann::json& value);
// What was there, for "got ...": its type and abridged text ("a string \"fast\"", "an array of 3").
std::string describe(const nlohmann::json& value);
// A number as users wrote it: "0.01", "1e-06", "100".
std::string format_number(double value);
// A key as a JSON pointer token (RFC 6901: '~' -> "~0", '/' -> "~1").
std::string escape_token(std::string_view key);

// A closed or open numeric interval, printed as "[0, 90]" or "(0, 1000]". Contains no NaN or inf.
struct Range {
  double lower;
  double upper;
  bool lower_open = false;
  bool upper_open = false;
  bool contains(double value) const;
  std::string to_string() const;
};

// Where a value sits: the input as the user knows it ("profiles/os1-64.json", "GET
// sensor/metadata") and a JSON pointer inside it ("" for the document, "/effects/2/sigma0_m").
struct Location {
  std::string source;
  std::string pointer;

  Location child(std::string_view key) const { return {source, pointer + "/" + escape_token(key)}; }
  Location child(size_t index) const { return {source, pointer + "/" + std::to_string(index)}; }
  std::string to_string() const { return source + ": " + (pointer.empty() ? "/" : pointer); }
  [[noreturn]] void fail(std::string_view what) const;
  // "must be <what>, got <describe(got)>"
  [[noreturn]] void fail_expected(std::string_view what, const nlohmann::json& got) const;
};

double read_number(const nlohmann::json& value, const Location& at, const Range& allowed);
double read_finite(const nlohmann::json& value, const Location& at);  // any finite number
// An integer, written 1024 or 1024.0 (some tools write every number as a float).
int64_t read_integer(const nlohmann::json& value, const Location& at, int64_t min, int64_t max);
std::string read_string(const nlohmann::json& value, const Location& at);
bool read_bool(const nlohmann::json& value, const Location& at);
// An array of numbers in `allowed`; of exactly `count` when given.
std::vector<double> read_numbers(const nlohmann::json& value, const Location& at, const Range& allowed,
                                 std::optional<size_t> count = std::nullopt);

enum class UnknownKeys { kReject, kKeep };

// One JSON object. With UnknownKeys::kReject every key must be among `allowed` (checked on
// construction: a misspelt key never silently keeps a default, as pbrt's ReportUnused).
class ObjectReader {
 public:
  // owner names the object in messages about unknown keys ("unknown key of dropout; ...").
  ObjectReader(const nlohmann::json& value, Location at, std::vector<std::string_view> allowed,
               UnknownKeys unknown = UnknownKeys::kReject, std::string_view owner = {});
  const nlohmann::json* find(std::string_view key) const;  // nullptr if absent
  // Throws "missing (expected <what>)" if absent.
  const nlohmann::json& at(std::string_view key, std::string_view what) const;
  const Location& location() const { return at_; }
  Location child(std::string_view key) const { return at_.child(key); }

 private:
  const nlohmann::json& object_;
  Location at_;
};

}  // namespace lidartwin::json_reader
