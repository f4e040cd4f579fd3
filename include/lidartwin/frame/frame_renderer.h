#pragma once
// The pixels of a frame: for each observed column, the cast from that column's pose, the effect
// chain, and the conversion into protocol units. Time, status and packet headers are not its
// business (ForwardModel stamps them); it renders whatever columns and poses it is given, so the
// daemon, `record` and the analysis (with a capture's own times) share it.
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/scan.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/profile/beam_intrinsics.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

// What rendering needs to know of a sensor, as configured.
struct RenderSetup {
  BeamIntrinsics beams;  // as served to clients (lidar_frame_azimuth_offset rotates them)
  LidarDataFormat format;
  double max_range_m = 100.0;  // the profile's range limit: the cast looks 1 m beyond it
  EffectChain chain;
  uint64_t seed = 0;
  float signal_gain = 1.0f;  // signal_multiplier
};

// The columns of one frame, indexed by measurement id: where the sensor was when each was observed,
// and whether it was observed at all (in the column window, with a pose to cast from).
struct FrameColumns {
  uint64_t frame_index = 0;       // keys the noise (with seed, column, beam)
  std::vector<Pose> poses;        // [W] world_from_sensor
  std::vector<uint8_t> observed;  // [W] 0: no cast, zero pixels
  std::vector<double> times_s;    // [W] since the sensor's clock began (effects' drift); empty: 0
};

class FrameRenderer {
 public:
  // scene and pool must outlive the renderer.
  FrameRenderer(const Scene& scene, RenderSetup setup, WorkerPool& pool);
  ~FrameRenderer();

  // Renders the pixels of columns [first, last) into scan (timestamps and status untouched), a
  // packet's columns at a time ([begin, end): columns_per_packet-aligned, clipped to [first, last)),
  // blocks on worker threads in any order. On the block's worker, prepare(begin, end), if given,
  // runs first and may fill columns' poses and observed flags for [begin, end) (so locating columns
  // runs in parallel too); done(begin, end), if given, runs once the block's pixels are in scan, so
  // packets are encoded in parallel with the cast. Output is identical for any thread count.
  using BlockHook = std::function<void(int begin, int end)>;
  void render(const FrameColumns& columns, int first, int last, Scan& scan, const BlockHook& done = nullptr,
              const BlockHook& prepare = nullptr) const;

  const LidarDataFormat& format() const;
  const BeamGeometry& geometry() const;
  float cast_range_m() const;  // Embree's tfar: where the cast stops looking for a surface

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
