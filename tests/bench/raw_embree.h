#pragma once
// Raw Embree on a sensor's own rays (DESIGN.md "Speed: what raw Embree means here"): the world rays
// the caster builds, prebuilt as 16-ray packets and cast through rtcIntersect16 with the coherent
// flag on all cores; only the packet copy and the intersect are timed. Packed as the caster packs
// them (one row of 16 neighbouring columns per packet) this is (a'), the reference every speed
// target is a ratio of. Shared by pipeline_bench and rig_bench.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <functional>
#include <thread>
#include <vector>

#include <embree3/rtcore.h>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin::bench {

// Wall time and the process's CPU time: on a shared machine the CPU-time rate (rays per CPU second
// times the thread count) estimates what idle cores would do.
struct Rate {
  double wall_per_s = 0;
  double cpu_per_s = 0;  // per CPU second, times threads
};

inline double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

class Stopwatch {
 public:
  Rate rate(double items, int threads) const {
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_).count();
    return {items / wall, items / (process_cpu_seconds() - cpu_) * threads};
  }

 private:
  std::chrono::steady_clock::time_point wall_ = std::chrono::steady_clock::now();
  double cpu_ = process_cpu_seconds();
};

// Runs task(i) for every index in [0, count) on `threads` threads, handing out 16 indices at a
// time (one shared counter per index would cost the reference a contended atomic per column).
inline void parallel_columns(int threads, int count, const std::function<void(int)>& task) {
  constexpr int kGrain = 16;
  std::atomic<int> next{0};
  const auto work = [&] {
    for (int b = next.fetch_add(kGrain); b < count; b = next.fetch_add(kGrain)) {
      for (int c = b; c < std::min(b + kGrain, count); ++c) task(c);
    }
  };
  std::vector<std::jthread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
}

// How the prebuilt rays are packed: a column's 16 consecutive rows (DESIGN.md's reference), or as
// ColumnCaster packs them, one row of 16 neighbouring columns (a RayStrip).
enum class Packing { kColumnRows, kCasterStrips };

// Which frames the rays are of: frame f observed from frame_spacing_s * f after the motion's start
// (0.1 s at 10 Hz: consecutive frames; more spreads them over a longer stretch of the motion).
struct RayFrames {
  int frames = 20;
  double frame_spacing_s = 0.1;
};

// The world rays of those frames, 16-ray packets, exactly the rays the caster builds: the pose at
// the column's time (the forward model's clock, frame/sensor_clock.h) applied to the SDK rays
// (protocol doc 7.2).
inline std::vector<RTCRay16> prebuilt_rays(const BeamIntrinsics& beams, const LidarDataFormat& format,
                                           const PoseSource& poses, RayFrames which, float tfar,
                                           Packing packing = Packing::kColumnRows) {
  const int w = format.columns_per_frame, h = format.pixels_per_column, per_column = (h + 15) / 16;
  const double frame_s = 1.0 / format.fps;
  const BeamGeometry geometry(beams, w);
  std::vector<RTCRay16> packets(static_cast<size_t>(which.frames) * static_cast<size_t>(w * per_column));
  std::vector<int> cast_index(static_cast<size_t>(h));  // [row]: its place k in the caster's cast order
  for (int k = 0; k < h; ++k) cast_index[static_cast<size_t>(geometry.cast_row(k))] = k;
  for (int f = 0; f < which.frames; ++f) {
    for (int m = 0; m < w; ++m) {
      const Pose pose = poses.at(poses.start_s() + f * which.frame_spacing_s + m * frame_s / w);
      const Eigen::Matrix3f rotation = pose.rotation.toRotationMatrix().cast<float>();
      const Eigen::Vector3f translation = pose.translation.cast<float>();
      for (int r = 0; r < h; ++r) {
        // kCasterStrips: columns 16g .. 16g + 15 share packets, packet k of the group holding
        // row cast_row(k) of each, lane m % 16.
        size_t index = static_cast<size_t>((f * w + m) * per_column + r / 16);
        int i = r % 16;
        if (packing == Packing::kCasterStrips) {
          index = static_cast<size_t>((f * w + m / 16 * 16) * per_column + cast_index[static_cast<size_t>(r)]);
          i = m % 16;
        }
        RTCRay16& p = packets[index];
        const BeamRay& ray = geometry.ray(r, m);
        const Eigen::Vector3f o = rotation * ray.origin_m + translation, d = rotation * ray.direction;
        p.org_x[i] = o.x(), p.org_y[i] = o.y(), p.org_z[i] = o.z();
        p.dir_x[i] = d.x(), p.dir_y[i] = d.y(), p.dir_z[i] = d.z();
        p.tnear[i] = ray.range_offset_m, p.tfar[i] = tfar, p.time[i] = 0, p.mask[i] = ~0u;
        p.id[i] = static_cast<unsigned>(r), p.flags[i] = 0;
      }
    }
  }
  return packets;
}

// Casts the prebuilt packets on `threads` threads; rays per second.
inline Rate raw_packets(const Scene& scene, int pixels_per_column, const std::vector<RTCRay16>& packets, int threads) {
  const int per_column = (pixels_per_column + 15) / 16;
  const int columns = static_cast<int>(packets.size()) / per_column;
  std::atomic<uint64_t> hits{0};
  const Stopwatch watch;
  parallel_columns(threads, columns, [&](int c) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) int valid[16];
    std::fill(valid, valid + 16, -1);
    uint64_t column_hits = 0;
    for (int k = 0; k < per_column; ++k) {
      alignas(64) RTCRayHit16 rh;
      std::memcpy(&rh.ray, &packets[static_cast<size_t>(c * per_column + k)], sizeof(RTCRay16));
      std::fill(rh.hit.geomID, rh.hit.geomID + 16, RTC_INVALID_GEOMETRY_ID);
      rtcIntersect16(valid, scene.embree_scene(), &context, &rh);
      for (int i = 0; i < 16; ++i) column_hits += rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
    }
    hits.fetch_add(column_hits, std::memory_order_relaxed);
  });
  if (hits.load() == 0) std::fprintf(stderr, "warning: no hits\n");
  return watch.rate(static_cast<double>(packets.size() * 16), threads);
}

}  // namespace lidartwin::bench
