#pragma once
// The range-noise laws that can stand in each other's place (lidar-physics.md E1, E2): a profile's
// sigma(r) may have the wrong form rather than wrong values, and a law of another form
// is then tried in its place, its own parameters fitted.
#include <optional>
#include <string_view>
#include <vector>

#include "effect_fit.h"

namespace lidartwin::analysis_detail {

// range_noise_linear and range_noise_piecewise: what a profile's range noise is.
bool is_range_noise_law(std::string_view effect);

// The index of the chain's range noise law; none if it has none.
std::optional<size_t> range_noise_index(const EffectChain& chain);

// The forms tried in place of the chain's range noise law at `index`, each a spec to fit there:
//  - signal_precision (E2): sigma^2 = floor^2 + k^2 (S + B) / S^2, k and floor free (needs the
//    chain's radiometry);
//  - for a datasheet table, the linear law over the table's span (sigma0 and sigma_max free);
//  - for a linear law, the datasheet table `datasheet` (a range_noise_piecewise effect, the
//    product line's): one sigma per plateau (its two knots tied, the ramps between plateaus kept
//    as the datasheet's), free where the rows have ranges; a plateau they do not reach keeps the
//    datasheet's value and is not counted.
// Forms whose effect the chain already has are left out.
std::vector<CandidateSpec> noise_law_forms(const EffectChain& chain, size_t index, const PixelTable& t,
                                           const FitRows& rows, const std::optional<nlohmann::json>& datasheet);

}  // namespace lidartwin::analysis_detail
