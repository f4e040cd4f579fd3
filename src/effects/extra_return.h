#pragma once
// A return besides the surface's (the window's dirt E16, fog's soft target E13), placed by strength
// as the default return_order STRONGEST_TO_WEAKEST does [S11]: first when it is stronger than the
// first return or there is none (the surface's then moves to second), else second when stronger
// than any second. Its REFLECTIVITY is 0: no surface's calibration applies to it.
#include <cstddef>

#include "lidartwin/effects/measurement.h"

namespace lidartwin::effects_detail {

inline void add_return(MeasuredColumn& measured, size_t beam, float range_m, float signal_photons) {
  if (measured.range_m[beam] == 0.0f || signal_photons > measured.signal_photons[beam]) {
    measured.range2_m[beam] = measured.range_m[beam];
    measured.signal2_photons[beam] = measured.signal_photons[beam];
    measured.reflectivity2[beam] = measured.reflectivity[beam];
    measured.range_m[beam] = range_m;
    measured.signal_photons[beam] = signal_photons;
    measured.reflectivity[beam] = 0.0f;
  } else if (measured.range2_m[beam] == 0.0f || signal_photons > measured.signal2_photons[beam]) {
    measured.range2_m[beam] = range_m;
    measured.signal2_photons[beam] = signal_photons;
    measured.reflectivity2[beam] = 0.0f;
  }
}

// The same in distribution: with probability p such a return is added to a pixel, whose returns
// so far (prediction.p_detect: earlier effects may have lost some) it joins. For a surface it
// makes a second return, and when it is the stronger it is the first return, far from the
// surface's range: the broad outlier component; where the surface gave nothing it is the only
// return, an outlier too. Where nothing was hit it is the only return.
inline void predict_added_return(Prediction& prediction, bool hit, double p, double signal_photons) {
  if (p <= 0.0) return;
  const double before = prediction.p_detect;
  const double after = 1.0 - (1.0 - before) * (1.0 - p);
  // Two returns: there were two already, or one and this adds the other.
  prediction.p_second += (before - prediction.p_second) * p;
  if (hit && after > 0.0) {
    const double displaced = signal_photons > prediction.signal_photons ? p * (1.0 - prediction.outlier_mix) : 0.0;
    prediction.outlier_mix = (before * (prediction.outlier_mix + displaced) + (1.0 - before) * p) / after;
  }
  prediction.p_detect = after;
}

}  // namespace lidartwin::effects_detail
