#pragma once
// Typed, bounds-checked access to a metadata document, in the project's one JSON vocabulary
// (lidartwin/json/json_reader.h): every failure is an InputError "<source>: <JSON pointer>: must be
// <what>, got <what was there>"; nothing here indexes a JSON value without checking its type first.
// Metadata keeps unknown keys on purpose: newer firmware adds them, and clients ignore them.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/json/json_reader.h"
#include "lidartwin/profile/beam_intrinsics.h"

namespace lidartwin::metadata_detail {

// A value inside the document together with the path that names it in error messages.
struct Node {
  const nlohmann::json* value = nullptr;
  std::string path;  // JSON pointer into the document as the user wrote it, e.g. "/data_format"
  const nlohmann::json& operator*() const { return *value; }
  const nlohmann::json* operator->() const { return value; }
};

class JsonReader {
 public:
  explicit JsonReader(std::string_view source) : source_(source) {}

  json_reader::Location at(const std::string& path) const { return {source_, path}; }
  // "must be <expected>, got <got>"
  [[noreturn]] void fail(const std::string& path, const std::string& expected, const std::string& got) const;
  [[noreturn]] void fail(const std::string& path, const std::string& message) const;

  // The member `key` of an object node; nullopt if the node is not an object or lacks the key.
  static std::optional<Node> child(const Node& parent, std::string_view key);

  std::string as_string(const Node& node) const;
  bool as_bool(const Node& node) const;
  double as_number(const Node& node) const;  // finite
  int64_t as_integer(const Node& node, int64_t min, int64_t max) const;
  std::vector<double> as_numbers(const Node& node, size_t count) const;  // exactly count
  std::vector<int> as_integers(const Node& node) const;                  // any length
  Mat4 as_mat4(const Node& node) const;

 private:
  std::string source_;
};

using json_reader::describe;

}  // namespace lidartwin::metadata_detail
