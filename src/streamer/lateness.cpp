#include "streamer/lateness.h"

#include <algorithm>
#include <cmath>

#include <spdlog/fmt/fmt.h>

namespace lidartwin::streamer_detail {

void LatenessHistogram::add(int64_t lateness_ns) {
  const int64_t clamped = std::max<int64_t>(lateness_ns, 0);  // early wake-ups count as on time
  const auto bin = std::min<int64_t>(clamped / 1000, kBins);
  ++bins_[static_cast<size_t>(bin)];
  ++count_;
  max_ns_ = std::max(max_ns_, clamped);
}

double LatenessHistogram::percentile_us(double fraction) const {
  if (count_ == 0) return 0.0;
  const auto rank = static_cast<uint64_t>(std::ceil(fraction * static_cast<double>(count_)));
  uint64_t seen = 0;
  for (size_t bin = 0; bin < bins_.size(); ++bin) {
    seen += bins_[bin];
    if (seen >= std::max<uint64_t>(rank, 1)) return static_cast<double>(bin) + 1.0;  // upper bin edge
  }
  return max_us();
}

std::string LatenessHistogram::summary() const {
  return fmt::format("p50 {:.0f} us, p99 {:.0f} us, max {:.0f} us (n = {})", percentile_us(0.5), percentile_us(0.99),
                     max_us(), count_);
}

}  // namespace lidartwin::streamer_detail
