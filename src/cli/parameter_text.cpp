#include "cli/parameter_text.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <fmt/format.h>

namespace lidartwin::cli {

std::vector<FittedParameter> parameters_to_show(const std::vector<FittedParameter>& params, size_t shown) {
  if (params.size() <= shown) return params;
  const auto strength = [](const FittedParameter& p) {
    const double half = 0.5 * (p.ci95_hi - p.ci95_lo);
    return half > 0.0 && std::isfinite(half) ? std::abs(p.value) / half : std::abs(p.value);
  };
  std::vector<size_t> order(params.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return strength(params[a]) > strength(params[b]); });
  order.resize(shown);
  std::sort(order.begin(), order.end());
  std::vector<FittedParameter> out;
  for (const size_t i : order) out.push_back(params[i]);
  return out;
}

std::string parameter_values_text(const std::vector<FittedParameter>& params, size_t shown) {
  std::string out;
  for (const FittedParameter& p : parameters_to_show(params, shown)) out += fmt::format(" {}={:.4g}", p.name, p.value);
  if (params.size() > shown) out += fmt::format(" ({} of {} parameters, the strongest)", shown, params.size());
  return out;
}

}  // namespace lidartwin::cli
