#include "metadata/json_reader.h"

#include <limits>

#include "lidartwin/error.h"

namespace lidartwin::metadata_detail {

void JsonReader::fail(const std::string& path, const std::string& expected, const std::string& got) const {
  at(path).fail("must be " + expected + ", got " + got);
}

void JsonReader::fail(const std::string& path, const std::string& message) const { at(path).fail(message); }

std::optional<Node> JsonReader::child(const Node& parent, std::string_view key) {
  if (!parent.value || !parent.value->is_object()) return std::nullopt;
  const auto it = parent.value->find(key);
  if (it == parent.value->end()) return std::nullopt;
  return Node{&*it, parent.path + "/" + std::string(key)};
}

std::string JsonReader::as_string(const Node& node) const { return json_reader::read_string(*node, at(node.path)); }

bool JsonReader::as_bool(const Node& node) const { return json_reader::read_bool(*node, at(node.path)); }

double JsonReader::as_number(const Node& node) const { return json_reader::read_finite(*node, at(node.path)); }

int64_t JsonReader::as_integer(const Node& node, int64_t min, int64_t max) const {
  return json_reader::read_integer(*node, at(node.path), min, max);
}

std::vector<double> JsonReader::as_numbers(const Node& node, size_t count) const {
  const std::string expected = std::to_string(count) + " numbers";
  if (!node->is_array() || node->size() != count) fail(node.path, expected, describe(*node));
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
    values.push_back(
        static_cast<int>(as_integer(element, std::numeric_limits<int>::min(), std::numeric_limits<int>::max())));
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
