#pragma once
// How fitted parameters are printed: every one of an effect with a few, the strongest of a table
// (E10 fits an offset and a scale per beam: 256 numbers that would bury the one beam that matters).
#include <cstddef>
#include <string>
#include <vector>

#include "lidartwin/analysis/diagnosis.h"

namespace lidartwin::cli {

// At most `shown` parameters: all of them if there are no more, else the `shown` farthest from 0
// in units of their 95 % half-width (by value where there is no interval), in their own order.
std::vector<FittedParameter> parameters_to_show(const std::vector<FittedParameter>& params, size_t shown = 6);

// " name=value name=value", with "(k of n parameters, the strongest)" after a table's.
std::string parameter_values_text(const std::vector<FittedParameter>& params, size_t shown = 6);

}  // namespace lidartwin::cli
