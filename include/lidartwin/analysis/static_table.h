#pragma once
// Static mode (`compare --static`): no scene, no pose. A motionless sensor's repeated frames give
// each pixel's temporal mean, spread and detection rate; the table puts the temporal mean where
// the scene's ideal range would be, so the same scoring and bins compare the measured spread and
// detection with the profile's prediction at the measured range and reflectivity. Bias cannot be
// judged this way (the mean is the data's own), nor anything needing the surface (incidence,
// material, edges).
#include <cstddef>

#include "lidartwin/analysis/pixel_table.h"

namespace lidartwin {

struct StaticTableSetup {
  const MeasuredCapture& capture;
  const EffectChain& chain;
  double max_range_m = 100.0;
  // A pixel enters the table when it returned in at least this fraction of the frames: fewer
  // returns say nothing reliable about where its surface is.
  double min_return_fraction = 0.5;
};

// Throws InputError when the capture has fewer than 2 frames, or no pixel returns often enough.
PixelTable build_static_table(const StaticTableSetup& setup);

}  // namespace lidartwin
