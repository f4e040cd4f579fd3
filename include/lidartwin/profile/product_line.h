#pragma once
// What an Ouster prod_line ("OS-1-64", "OS-0-32-U1", "OS-DOME-128") says about the product, in one
// place for profiles and metadata (protocol doc 3.1).
#include <optional>
#include <string_view>

namespace lidartwin {

// The beam count the SDK reads from a product line: it splits on '-' and takes the third field
// when the second is a digit run or "DOME" ("OS-1-64" -> 64, "OS-0-32-U1" -> 32); nullopt otherwise.
std::optional<int> beam_count_of(std::string_view prod_line);
// The SDK's default lidar_origin_to_beam_origin_mm by family: OS-0 27.67, OS-1 15.806, OS-2
// 13.762, anything else (Gen 1) 12.163.
double default_lidar_origin_to_beam_origin_mm(std::string_view prod_line);
// The shape a profile's prod_line must have: "OS-<0|1|2>-<beams>[-<variant>]", 1-4 digit beams,
// a variant of letters, digits and '_'.
bool is_current_product_line(std::string_view prod_line);

}  // namespace lidartwin
