#pragma once
// Light lost between the sensor and a surface (a dirty window E16, fog E13): the returns' SIGNAL
// falls by the two-way transmission, and so does the REFLECTIVITY the sensor calibrates from it in
// its linear band (0-100); the retroreflector band above 100 is left as it was (its logarithmic
// scale belongs to radiometry).
#include <cstddef>

#include "lidartwin/effects/measurement.h"

namespace lidartwin::effects_detail {

inline void attenuate(MeasuredColumn& measured, size_t beam, float transmission) {
  measured.signal_photons[beam] *= transmission;
  measured.signal2_photons[beam] *= transmission;
  if (measured.reflectivity[beam] <= 100.0f) measured.reflectivity[beam] *= transmission;
  if (measured.reflectivity2[beam] <= 100.0f) measured.reflectivity2[beam] *= transmission;
}

}  // namespace lidartwin::effects_detail
