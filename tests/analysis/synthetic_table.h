#pragma once
// A pixel table made in a test, where the truth is known: 64 beams x 512 columns x 4 frames of a
// scene at 1-60 m (by beam and column), the model saying sigma = 20 mm and certain detection
// everywhere. The tests then write what was "measured".
#include <cstddef>
#include <cstdint>

#include "lidartwin/analysis/pixel_table.h"

namespace lidartwin::test {

inline constexpr size_t kSyntheticPixels = 4 * 512 * 64;

// Everything but range_m: where each pixel is, its ideal return and the model's prediction.
inline PixelTable synthetic_layout() {
  PixelTable t;
  t.resize(kSyntheticPixels);
  for (size_t i = 0; i < kSyntheticPixels; ++i) {
    const auto beam = static_cast<uint16_t>(i % 64);
    const auto column = static_cast<uint16_t>(i / 64 % 512);
    t.frame[i] = static_cast<uint32_t>(i / (64 * 512));
    t.beam[i] = beam;
    t.column[i] = column;
    t.time_s[i] = t.frame[i] * 0.1 + column * 0.1 / 512;
    const double ideal = 1.0 + 59.0 * ((beam * 7 + column) % 512) / 512.0;
    t.ideal_range_m[i] = static_cast<float>(ideal);
    t.set_incidence(i, static_cast<float>(beam % 80));
    t.material_reflectivity[i] = 0.5f;
    t.azimuth_deg[i] = static_cast<float>(360.0 - 360.0 * column / 512);
    t.predicted_sigma_m[i] = 0.02f;
    t.p_detect[i] = 1.0f;
    t.window_min_m[i] = 0.3f;
    t.window_max_m[i] = 101.0f;
    t.step_m[i] = 0.001f;
    t.expected_signal[i] = 500.0f;
    t.expected_near_ir[i] = 50.0f;
    t.edge[i] = PixelTable::kFarPixels;
    t.retro[i] = PixelTable::kFarPixels;
  }
  return t;
}

}  // namespace lidartwin::test
