#pragma once
// A rate in words, with the digits that tell two rates apart.
#include <algorithm>
#include <cmath>
#include <string>

#include <fmt/format.h>

namespace lidartwin::analysis_detail {

// Near 0 (outliers) three decimals; near 1 (detection) the misses' share to two significant
// digits ("99.95 %", "99.9997 %"), so that "100 %" means 1 and two rates that differ read apart.
inline std::string percent(double f) {
  if (f < 0.001) return fmt::format("{:.3f} %", 100 * f);
  if (f < 0.1) return fmt::format("{:.1f} %", 100 * f);
  if (f > 0.99 && f < 1.0) {
    const double missing = 100.0 * (1.0 - f);
    const int decimals = std::clamp(1 - static_cast<int>(std::floor(std::log10(missing))), 2, 6);
    const std::string text = fmt::format("{:.{}f} %", 100 * f, decimals);
    return text.rfind("100", 0) == 0 ? fmt::format("{:.{}f} %", 100.0 - std::pow(10.0, -decimals), decimals) : text;
  }
  return fmt::format("{:.0f} %", 100 * f);
}

}  // namespace lidartwin::analysis_detail
