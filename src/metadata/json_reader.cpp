#include "metadata/json_reader.h"

#include <cmath>
#include <limits>

#include "lidartwin/error.h"

namespace lidartwin::metadata_detail {

std::string describe(const nlohmann::json& value) {
  if (value.is_array()) return "an array of " + std::to_string(value.size());
  if (value.is_object()) return "an object";
  std::string text = value.dump();
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  return std::string(value.type_name()) + " " + text;
}

void JsonReader::fail(const std::string& path, const std::string& expected, const std::string& got) const {
  fail(path, "expected " + expected + ", got " + got);
}

void JsonReader::fail(const std::string& path, const std::string& message) const {
  throw InputError(source_ + ": " + (path.empty() ? "/" : path) + ": " + message);
}

std::optional<Node> JsonReader::child(const Node& parent, std::string_view key) {
  if (!parent.value || !parent.value->is_object()) return std::nullopt;
  const auto it = parent.value->find(key);
  if (it == parent.value->end()) return std::nullopt;
  return Node{&*it, parent.path + "/" + std::string(key)};
}

std::string JsonReader::as_string(const Node& node) const {
  if (!node->is_string()) fail(node.path, "a string", describe(*node));
  return node->get<std::string>();
}

bool JsonReader::as_bool(const Node& node) const {
  if (!node->is_boolean()) fail(node.path, "true or false", describe(*node));
  return node->get<bool>();
}

double JsonReader::as_number(const Node& node) const {
  if (!node->is_number()) fail(node.path, "a number", describe(*node));
  const double value = node->get<double>();
  if (!std::isfinite(value)) fail(node.path, "a finite number", describe(*node));
  return value;
}

// Integers may be written as 1024 or 1024.0 (some tools write every number as a float).
int64_t JsonReader::as_integer(const Node& node, int64_t min, int64_t max) const {
  const std::string expected = "an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
  if (node->is_number_unsigned()) {
    const uint64_t value = node->get<uint64_t>();
    if (value > static_cast<uint64_t>(max)) fail(node.path, expected, describe(*node));
    return static_cast<int64_t>(value);
  }
  if (node->is_number_integer()) {
    const int64_t value = node->get<int64_t>();
    if (value < min || value > max) fail(node.path, expected, describe(*node));
    return value;
  }
  if (node->is_number_float()) {
    const double value = node->get<double>();
    if (std::isfinite(value) && value == std::floor(value) && value >= static_cast<double>(min) &&
        value <= static_cast<double>(max)) {
      return static_cast<int64_t>(value);
    }
  }
  fail(node.path, expected, describe(*node));
}

std::vector<double> JsonReader::as_numbers(const Node& node, size_t count) const {
  const std::string expected = std::to_string(count) + " numbers";
  if (!node->is_array()) fail(node.path, expected, describe(*node));
  if (node->size() != count) fail(node.path, expected, std::to_string(node->size()));
  std::vector<double> values;
  values.reserve(count);
  for (size_t i = 0; i < count; ++i) {
    values.push_back(as_number(Node{&(*node)[i], node.path + "/" + std::to_string(i)}));
  }
  return values;
}

std::vector<int> JsonReader::as_integers(const Node& node) const {
  if (!node->is_array()) fail(node.path, "an array of integers", describe(*node));
  std::vector<int> values;
  values.reserve(node->size());
  for (size_t i = 0; i < node->size(); ++i) {
    const Node element{&(*node)[i], node.path + "/" + std::to_string(i)};
    values.push_back(static_cast<int>(as_integer(element, std::numeric_limits<int>::min(),
                                                 std::numeric_limits<int>::max())));
  }
  return values;
}

Mat4 JsonReader::as_mat4(const Node& node) const {
  const std::vector<double> values = as_numbers(node, 16);
  Mat4 matrix{};
  for (size_t i = 0; i < 16; ++i) matrix[i] = values[i];
  return matrix;
}

}  // namespace lidartwin::metadata_detail
