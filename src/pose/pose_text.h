#pragma once
// Shared by parse_pose and the TUM reader: numbers from a line of text, and a validated Pose.
#include <optional>
#include <string_view>
#include <vector>

#include "lidartwin/pose/pose.h"

namespace lidartwin::pose_detail {

// Blank- (or comma-) separated numbers; nullopt if a token is not a number.
std::optional<std::vector<double>> parse_numbers(std::string_view text);
// v = {x, y, z, qx, qy, qz, qw}. Throws InputError "<where>: ..." for non-finite values or a
// zero-norm quaternion; normalizes the quaternion.
Pose pose_from_numbers(const double* v, std::string_view where);

}  // namespace lidartwin::pose_detail
