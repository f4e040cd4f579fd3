// Pose values and their text form ("x y z qx qy qz qw", the TUM order).
#include "lidartwin/pose/pose.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "lidartwin/error.h"
#include "pose/pose_text.h"

namespace lidartwin {
namespace pose_detail {
namespace {
bool is_space(char c) { return c == ' ' || c == '\t' || c == ',' || c == '\r' || c == '\n'; }
}  // namespace

std::optional<std::vector<double>> parse_numbers(std::string_view text) {
  std::vector<double> values;
  size_t i = 0;
  while (i < text.size()) {
    if (is_space(text[i])) {
      ++i;
      continue;
    }
    size_t end = i;
    while (end < text.size() && !is_space(text[end])) ++end;
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(text.data() + i, text.data() + end, value);
    if (ec != std::errc() || ptr != text.data() + end) return std::nullopt;
    values.push_back(value);
    i = end;
  }
  return values;
}

Pose pose_from_numbers(const double* v, std::string_view where) {
  for (int i = 0; i < 7; ++i) {
    if (!std::isfinite(v[i])) throw InputError(std::string(where) + ": pose values must be finite");
  }
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);  // Eigen's constructor order is (w, x, y, z)
  const double norm = q.norm();
  if (!(norm > 1e-12)) throw InputError(std::string(where) + ": quaternion qx qy qz qw has zero norm");
  Pose pose;
  pose.rotation = Eigen::Quaterniond(q.coeffs() / norm);
  pose.translation = Eigen::Vector3d(v[0], v[1], v[2]);
  return pose;
}

}  // namespace pose_detail

std::string to_string(const Pose& pose) {
  const auto& t = pose.translation;
  const auto& q = pose.rotation;
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g", t.x(), t.y(), t.z(), q.x(), q.y(), q.z(),
                q.w());
  return buffer;
}

Pose parse_pose(std::string_view text) {
  const std::string where = "pose \"" + std::string(text) + "\"";
  const auto values = pose_detail::parse_numbers(text);
  if (!values) throw InputError(where + ": expected 7 numbers \"x y z qx qy qz qw\", got a non-number");
  if (values->size() != 7) {
    throw InputError(where + ": expected 7 numbers \"x y z qx qy qz qw\", got " + std::to_string(values->size()));
  }
  return pose_detail::pose_from_numbers(values->data(), where);
}

}  // namespace lidartwin
