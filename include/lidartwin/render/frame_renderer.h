#pragma once
// The sensor model forward: for each column, the pose at that column's time, the cast, the effect
// chain, and the conversion into a Scan in protocol units. Used by `record` and by the daemon.
#include <cstdint>
#include <functional>
#include <memory>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/scan.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

struct RenderConfig {
  uint64_t seed = 0;
  int threads = 0;  // 0 = all cores
  float signal_gain = 1.0f;
  // Column timestamps (6.3) = clock_origin_ns + round(frame_start_s * 1e9) + floor(m * 1e9 / (W * fps)):
  // the sensor clock's reading at trajectory time 0. The streamer restamps columns itself.
  int64_t clock_origin_ns = 0;
};

class FrameRenderer {
 public:
  FrameRenderer(const Scene& scene, const SensorProfile& profile, EffectChain chain,
                const LidarDataFormat& format, RenderConfig config);
  ~FrameRenderer();

  // Renders columns [first, last) of frame `frame_index` (for the RNG key) into scan. Column m is
  // observed at frame_start_s + m / (W * fps) with trajectory.at(that time). Columns outside the
  // format's column_window get status 0 and zero pixels. Output is identical for any thread count.
  void render(uint64_t frame_index, double frame_start_s, const Trajectory& trajectory, int first, int last,
              Scan& scan) const;

  // The same, calling block_done(begin, end) on a worker thread as soon as the columns
  // [begin, end) of one packet (columns_per_packet-aligned, clipped to [first, last)) are in scan,
  // so packets can be encoded in parallel with the cast. Blocks finish in any order.
  using BlockDone = std::function<void(int begin, int end)>;
  void render(uint64_t frame_index, double frame_start_s, const Trajectory& trajectory, int first, int last,
              Scan& scan, const BlockDone& block_done) const;

  const BeamGeometry& geometry() const;
  int threads() const;
  float cast_range_m() const;  // Embree's tfar: where the cast stops looking for a surface

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
