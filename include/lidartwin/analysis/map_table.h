#pragma once
// Map mode (`compare --map`): no scene, a moving sensor. Each pixel's ideal range is its beam's
// intersection with a surface fitted to the points of the OTHER frames around it (the frames
// placed by the registered or given trajectory), so the pixel's own noise is not in its reference;
// the surface's normal gives the incidence, the measured REFLECTIVITY the reflectivity (SIGNAL then
// follows through the profile's radiometry, which the diagnosis refits to the measured SIGNAL).
// The reference's own error, known from the fit, is added to the predicted spread so that the
// measured spread is not judged against too small a sigma (docs/compare-report.md).
//
// Only returns are compared, and only where the other frames show a surface (the rules, each
// counted in MapExclusions): not within a pixel of a depth step in its own frame; at least 12
// points from at least 2 other frames within the patch; a smooth surface there (the fit's RMS
// below a third of the patch's extent: vegetation, wires, corners fail it); not farther than
// max(1 m, 10 %) from it (a moving object, or what the other frames saw through a gap); incidence
// below 85 degrees.
//
// Within a frame (MapTableSetup::within_frame, and a capture of one frame, as most published sample
// captures are): the surface is fitted to the same frame's other returns around the pixel, the pixel
// itself left out, which keeps its own noise out of its reference as leaving its frame out does.
// It needs no trajectory: at a patch's scale (a few columns, under a millisecond apart) the frame's
// own motion is far below the noise. What it cannot see: noise its neighbours share (a per-frame
// or per-column range offset), which another frame's points would not.
#include <cstddef>
#include <functional>

#include "lidartwin/analysis/pixel_table.h"

namespace lidartwin {

struct MapTableSetup {
  const MeasuredCapture& capture;
  const PoseSource& poses;     // world_from_sensor on the capture's clock, shifted by time_offset_s
  double time_offset_s = 0.0;  // pose time = column timestamp + offset
  const EffectChain& chain;
  double max_range_m = 100.0;
  int neighbour_frames = 3;   // frames on each side whose points make a pixel's reference
  bool within_frame = false;  // the pixel's own frame's other returns make its reference instead
  // The frames whose returns are scored (the table's frame 0 is first_scored_frame); every frame
  // of the capture makes references. A fit on some frames and a judgement on the others (held-out
  // frames) then both see surfaces made of the whole capture.
  size_t first_scored_frame = 0;
  size_t scored_frames = 0;  // 0: all from first_scored_frame on
  std::function<void(double fraction)> progress = nullptr;
};

struct MapExclusions {
  size_t returns = 0;      // returns of valid columns, within the range limits
  size_t compared = 0;     // in the table
  size_t edge = 0;         // beside a depth step in their own frame
  size_t unsupported = 0;  // too few points of other frames around them
  size_t not_surface = 0;  // the points around them are no smooth surface
  size_t off_surface = 0;  // far from the surface the other frames saw
  size_t grazing = 0;      // incidence above 85 degrees
};

struct MapTable {
  PixelTable table;
  MapExclusions excluded;
};

// Throws InputError when the capture has fewer than two frames (unless within_frame) or no pixel
// can be compared.
MapTable build_map_table(const MapTableSetup& setup, WorkerPool& pool);

}  // namespace lidartwin
