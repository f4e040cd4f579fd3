#pragma once
// Send lateness (time sent - packet deadline) as a histogram, for percentiles without storing
// every sample: 1 us bins up to 20 ms, then one overflow bin.
#include <array>
#include <cstdint>
#include <string>

namespace lidartwin::streamer_detail {

class LatenessHistogram {
 public:
  void add(int64_t lateness_ns);
  uint64_t count() const { return count_; }
  double percentile_us(double fraction) const;  // fraction in [0, 1]
  double max_us() const { return static_cast<double>(max_ns_) / 1e3; }
  std::string summary() const;  // "p50 12 us, p99 48 us, max 131 us (n = 3200)"

 private:
  static constexpr int kBins = 20'000;
  std::array<uint32_t, kBins + 1> bins_{};
  uint64_t count_ = 0;
  int64_t max_ns_ = 0;
};

}  // namespace lidartwin::streamer_detail
