#pragma once
// A return besides the surface's (the window's dirt E16, fog's soft target E13), placed by strength
// as the default return_order STRONGEST_TO_WEAKEST does [S11]: first when it is stronger than the
// first return or there is none (the surface's then moves to second), else second when stronger
// than any second. Its REFLECTIVITY is 0: no surface's calibration applies to it.
#include <cstddef>

#include "lidartwin/caster/ideal_return.h"
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

// The same for a return at a known range (range_m, spread sigma_m: a halo at the retroreflector's
// range, E8): where it comes first (stronger than the surface's, the surface's lost, or no surface)
// it is the mixture's partner component, narrow, not the broad outlier one; off a surface it is
// all there is (partner_mix 1). Where that component is taken (an edge partner, E6), as above.
inline void predict_added_return_at(Prediction& prediction, const IdealReturn& ideal, double p, double signal_photons,
                                    double range_m, double sigma_m) {
  if (prediction.partner_mix > 0.0 || p <= 0.0) {
    predict_added_return(prediction, ideal.hit(), p, signal_photons);
    return;
  }
  const double before = prediction.p_detect, after = 1.0 - (1.0 - before) * (1.0 - p);
  prediction.p_second += (before - prediction.p_second) * p;
  const double first = signal_photons > prediction.signal_photons ? p : 0.0;  // displaces the surface's
  const double added = before * first + (1.0 - before) * p;
  const double surface = before * (1.0 - first);
  const double gaussian = surface * (1.0 - prediction.outlier_mix);
  prediction.outlier_mix = surface * prediction.outlier_mix / after;
  prediction.partner_mix = added + gaussian > 0.0 ? added / (added + gaussian) : 0.0;
  prediction.partner_offset_m = range_m - (static_cast<double>(ideal.range_m) + prediction.bias_m);
  prediction.partner_extra_variance_m2 = sigma_m * sigma_m - prediction.variance_m2;
  prediction.p_detect = after;
  // E6's echoes (the pixel's own only: a partner would hold this component) are no longer the
  // pixel's whole story; the effects after this one read its mean signal.
  prediction.echo_count = prediction.own_echoes = 0;
}

}  // namespace lidartwin::effects_detail
