#pragma once
// The values an effect chain produces and predicts for one pixel.
#include <cstdint>
#include <limits>

namespace lidartwin {

// One pixel as measured, in physical units (the renderer converts to protocol units).
struct Measurement {
  float range_m = 0.0f;  // 0 = no return
  float signal_photons = 0.0f;
  float near_ir_photons = 0.0f;
  float reflectivity = 0.0f;  // calibrated reflectivity byte value, 0..255
  float range2_m = 0.0f;      // second return (dual profiles), 0 = none
  float signal2_photons = 0.0f;
  float reflectivity2 = 0.0f;
};

// The distribution of the measured range of one pixel given its ideal return, as the analysis
// uses it for likelihoods: a detection probability, and when detected a mixture of
// N(range + bias, variance) with weight (1 - outlier_mix) and a broad outlier component.
// When range limits apply, a detected range lies in [window_min_m, window_max_m]: the Gaussian is
// truncated there, and p_detect already includes its probability mass inside the window.
struct Prediction {
  double bias_m = 0.0;
  double variance_m2 = 0.0;
  double p_detect = 1.0;
  double outlier_mix = 0.0;
  double quantization_step_m = 0.0;  // 0 = continuous
  double window_min_m = 0.0;
  double window_max_m = std::numeric_limits<double>::infinity();
  double signal_photons = 0.0;   // expected SIGNAL (radiometry), for signal-dependent effects
  double near_ir_photons = 0.0;  // expected NEAR_IR (radiometry)
};

// What the chain knows beyond the pixel: the random-stream key and the wire format's limits.
struct ColumnContext {
  uint64_t seed = 0;
  uint64_t frame = 0;
  uint32_t column = 0;            // measurement id
  float range_step_m = 0.001f;    // 0.001 (RNG19, LEGACY) or 0.008 (RNG15 profiles)
  float max_wire_range_m = 524.287f;
  float signal_gain = 1.0f;       // signal_multiplier and lidar-mode integration (E18)
};

}  // namespace lidartwin
