// The emulator's speed against raw Embree (DESIGN.md "Speed: what raw Embree means here"), for an
// OS1-128 at 2048x10 in scenes/plant.glb, from two poses: the drone's inspection lap (21 % of the
// points carry a return) and standing 1.7 m above the ground among the plant's structures (83 %):
//   (a) raw reference: the same world rays, each column's 128 beams as 16-ray packets through
//       rtcIntersect16 with RTC_INTERSECT_CONTEXT_FLAG_COHERENT, all cores (rays prebuilt, only
//       the packet copy and the intersect are timed);
//   (a') the same rays packed as the caster packs them (ColumnCaster: one row of 16 neighbouring
//       columns per packet), timed the same way: Embree's speed on these rays the fastest way this
//       project knows, against which (c) and (d) are also given;
//   (b) the same rays one per rtcIntersect1 call, all cores (for context);
//   (c) the pipeline: pose per column, cast, effect chain, protocol units, packet encode with
//       CRC-64 into packet buffers (the ForwardModel);
//   (d) `record` end to end: (c) plus the pcap writing (IP fragmentation, checksums, the file), the
//       library call `lidartwin record` makes, into a temporary directory.
// Each repeat runs (a), (c) and (d) back to back and takes the ratios (c)/(a) and (d)/(a); the
// ratios printed are medians over the repeats (this host's speed drifts by tens of percent between
// runs, much less within a pair), the rates the best of each.
// Usage: pipeline_bench [frames=20] [threads=0 (all cores)] [repeats=5] [only=all|pipeline|record]
//                       [pose=both|drone|ground]
// ("pipeline" runs only (c), "record" only (d), for profiling).
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <embree3/rtcore.h>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/caster/column_caster.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/forward_model.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/record/recorder.h"
#include "lidartwin/scene/scene.h"
#include "raw_embree.h"
#include "support/every_effect_chain.h"

namespace {

using namespace lidartwin;
using bench::Packing;
using bench::parallel_columns;
using bench::Rate;
using bench::Stopwatch;

const std::filesystem::path kSource = LIDARTWIN_SOURCE_DIR;

// The ground pose: 1.7 m above the plant's ground, level, looking along +x.
constexpr const char* kGroundPose = "15 9 1.7 0 0 0 1";  // under the cross rack: 89 % of rays return

struct Setup {
  SensorProfile profile = load_profile("os1-128");
  Scene scene = Scene::load(kSource / "scenes/plant.glb");
  Metadata metadata = make_metadata(
      [] {
        SensorInfo info;
        info.prod_sn = "992200000001";
        info.initialization_id = 1;
        return info;
      }(),
      profile.beams,
      [] {
        nlohmann::json config = default_config_params();
        config["lidar_mode"] = "2048x10";
        config["udp_profile_lidar"] = "RNG19_RFL8_SIG16_NIR16";
        return config;
      }());
  const LidarDataFormat& format() const { return metadata.format; }
};

struct Scenario {
  const char* name;
  std::unique_ptr<PoseSource> poses;
};

// Where column m of frame f is observed from: the forward model's clock (frame/sensor_clock.h).
Pose column_pose(const PoseSource& poses, int f, int m, int w) {
  return poses.at(poses.start_s() + f / 10.0 + m / (10.0 * w));
}

std::vector<RTCRay16> prebuilt_rays(const Setup& s, const PoseSource& poses, int frames, float tfar,
                                    Packing packing = Packing::kColumnRows) {
  return bench::prebuilt_rays(s.profile.beams, s.format(), poses, {frames, 0.1}, tfar, packing);
}

Rate raw_packets(const Setup& s, const std::vector<RTCRay16>& packets, int threads) {
  return bench::raw_packets(s.scene, s.format().pixels_per_column, packets, threads);
}

Rate raw_single(const Setup& s, const std::vector<RTCRay16>& packets, int threads) {
  std::atomic<uint64_t> hits{0};
  const Stopwatch watch;
  parallel_columns(threads, static_cast<int>(packets.size()), [&](int k) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    const RTCRay16& p = packets[static_cast<size_t>(k)];
    uint64_t packet_hits = 0;
    for (int i = 0; i < 16; ++i) {
      RTCRayHit rh{};
      rh.ray = {p.org_x[i], p.org_y[i], p.org_z[i], p.tnear[i], p.dir_x[i], p.dir_y[i],
                p.dir_z[i], 0.0f,       p.tfar[i],  ~0u,        p.id[i],    0};
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(s.scene.embree_scene(), &context, &rh);
      packet_hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
    hits.fetch_add(packet_hits, std::memory_order_relaxed);
  });
  return watch.rate(static_cast<double>(packets.size() * 16), threads);
}

// ColumnCaster alone (pose per column, packets, IdealReturns, edges): the caster's share of (c).
Rate caster_only(const Setup& s, const PoseSource& poses, const BeamGeometry& geometry, float tfar, int frames,
                 int threads) {
  const ColumnCaster caster(s.scene, geometry, tfar);
  const int w = s.format().columns_per_frame;
  constexpr int kBlock = 16;  // a packet's columns, as the renderer casts them
  const Stopwatch watch;
  parallel_columns(threads, frames * w / kBlock, [&](int b) {
    thread_local std::vector<std::vector<IdealReturn>> block(kBlock);
    std::array<Pose, kBlock> pose_of;
    std::array<ColumnCaster::Column, kBlock> columns;
    for (int k = 0; k < kBlock; ++k) {
      const int c = b * kBlock + k, f = c / w, m = c % w;
      block[static_cast<size_t>(k)].resize(static_cast<size_t>(geometry.rows()));
      pose_of[static_cast<size_t>(k)] = column_pose(poses, f, m, w);
      columns[static_cast<size_t>(k)] = {m, &pose_of[static_cast<size_t>(k)], block[static_cast<size_t>(k)]};
    }
    caster.cast(columns);
  });
  return watch.rate(static_cast<double>(frames) * w * geometry.rows(), threads);
}

struct PipelineRate {
  Rate pixels;          // points of the cloud (every pixel: a return or range 0)
  double return_share;  // of the pixels, those with a return
};

PipelineRate pipeline(const Setup& s, const ForwardModel& model, int frames, int threads) {
  const int w = s.format().columns_per_frame;
  EncodedFrame encoded = model.make_frame_buffer();
  const Stopwatch watch;
  for (int f = 0; f < frames; ++f) model.render(static_cast<uint64_t>(f), encoded);
  const double pixels = static_cast<double>(frames) * w * s.format().pixels_per_column;
  const Rate rate = watch.rate(pixels, threads);
  // The share of returns, from the last frame and outside the timing (a serial pass over it).
  const auto& ranges = encoded.scan.channels[static_cast<size_t>(ChannelField::kRange)];
  const auto returns = std::count_if(ranges.begin(), ranges.end(), [](uint32_t range) { return range != 0; });
  return {rate, static_cast<double>(returns) / static_cast<double>(ranges.size())};
}

EffectChain chain_of(const Setup& s) { return EffectChain::from_json(s.profile.effects, "os1-128"); }

// (d): what `lidartwin record` runs, into a temporary directory (with the profile's chain unless
// told another).
Rate record_path(const Setup& s, const PoseSource& poses, int frames, int threads,
                 const std::optional<EffectChain>& chain = std::nullopt) {
  const auto dir = std::filesystem::temp_directory_path() / "lidartwin_pipeline_bench";
  const Stopwatch watch;
  record({s.scene, poses, s.profile.max_range_m, chain.value_or(chain_of(s)), s.metadata, 1, threads, frames, dir},
         [](int) {});
  const Rate rate =
      watch.rate(static_cast<double>(frames) * s.format().columns_per_frame * s.format().pixels_per_column, threads);
  std::filesystem::remove_all(dir);
  return rate;
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values.empty() ? 0.0 : values[values.size() / 2];
}

void run_scenario(const Setup& s, const Scenario& scenario, int frames, int threads, int repeats,
                  const std::string& only) {
  if (only == "record") {
    std::printf("%s: (d) record end to end, M pixels/s:", scenario.name);
    for (int r = 0; r < repeats; ++r)
      std::printf(" %.2f", record_path(s, *scenario.poses, frames, threads).wall_per_s * 1e-6);
    std::printf("\n");
    return;
  }
  const bool only_pipeline = only == "pipeline";
  WorkerPool pool(threads);
  ForwardModelSetup setup;
  setup.render = {s.metadata.beams, s.format(), s.profile.max_range_m, chain_of(s), 1, 1.0f};
  setup.pose_origin_s = scenario.poses->start_s();
  const ForwardModel model(s.scene, *scenario.poses, setup, pool);
  const auto rays =
      only_pipeline ? std::vector<RTCRay16>() : prebuilt_rays(s, *scenario.poses, frames, model.cast_range_m());
  const auto quad_rays = only_pipeline
                             ? std::vector<RTCRay16>()
                             : prebuilt_rays(s, *scenario.poses, frames, model.cast_range_m(), Packing::kCasterStrips);
  Rate raw16, raw_quads, raw1, cast, recorded;
  PipelineRate pipe{};
  const auto keep_best = [](Rate& best, const Rate& r) {
    best.wall_per_s = std::max(best.wall_per_s, r.wall_per_s);
    best.cpu_per_s = std::max(best.cpu_per_s, r.cpu_per_s);
  };
  std::vector<double> pipeline_ratios, record_ratios, floor_ratios, pipeline_quad_ratios, record_quad_ratios,
      caster_quad_ratios, floor_quad_ratios;
  for (int r = 0; r < repeats; ++r) {
    const Rate a = only_pipeline ? Rate{} : raw_packets(s, rays, threads);
    const PipelineRate p = pipeline(s, model, frames, threads);
    keep_best(pipe.pixels, p.pixels);
    pipe.return_share = p.return_share;
    if (only_pipeline) continue;
    const Rate d = record_path(s, *scenario.poses, frames, threads);
    const Rate floor = record_path(s, *scenario.poses, frames, threads, EffectChain());
    floor_ratios.push_back(floor.wall_per_s / a.wall_per_s);
    const Rate a_quads = raw_packets(s, quad_rays, threads);
    floor_quad_ratios.push_back(floor.wall_per_s / a_quads.wall_per_s);
    keep_best(raw16, a);
    keep_best(raw_quads, a_quads);
    keep_best(recorded, d);
    pipeline_ratios.push_back(p.pixels.wall_per_s / a.wall_per_s);
    record_ratios.push_back(d.wall_per_s / a.wall_per_s);
    pipeline_quad_ratios.push_back(p.pixels.wall_per_s / a_quads.wall_per_s);
    record_quad_ratios.push_back(d.wall_per_s / a_quads.wall_per_s);
    std::fprintf(stderr, "  repeat %d: (a) %.2f, (c) %.2f, (d) %.2f M/s\n", r, a.wall_per_s * 1e-6,
                 p.pixels.wall_per_s * 1e-6, d.wall_per_s * 1e-6);
    keep_best(raw1, raw_single(s, rays, threads));
    const Rate caster = caster_only(s, *scenario.poses, model.geometry(), model.cast_range_m(), frames, threads);
    keep_best(cast, caster);
    caster_quad_ratios.push_back(caster.wall_per_s / a_quads.wall_per_s);
  }
  const double real_time = 2048.0 * 128 * 10;  // pixels per second of a real sensor
  std::printf("\n%s: returns %.0f %% of points\n", scenario.name, 100 * pipe.return_share);
  std::printf("                                          wall clock   | CPU time x threads (idle-machine estimate)\n");
  const auto row = [](const char* name, const Rate& r) {
    std::printf("%-40s %8.2f M/s | %8.2f M/s\n", name, r.wall_per_s * 1e-6, r.cpu_per_s * 1e-6);
  };
  row("(a) raw Embree rtcIntersect16 coherent", raw16);
  row("(a') the same, the caster's packets", raw_quads);
  row("(b) raw Embree rtcIntersect1", raw1);
  row("    ColumnCaster alone (rays)", cast);
  row("(c) pipeline points (pixels)", pipe.pixels);
  row("(d) record end to end (pixels)", recorded);
  std::printf("    pipeline %.1fx real time, record %.1fx (wall)\n", pipe.pixels.wall_per_s / real_time,
              recorded.wall_per_s / real_time);
  if (!pipeline_ratios.empty()) {
    std::printf("ratio (c) pipeline / raw (a): median %.3f (min %.3f, max %.3f; target 0.8)\n", median(pipeline_ratios),
                *std::min_element(pipeline_ratios.begin(), pipeline_ratios.end()),
                *std::max_element(pipeline_ratios.begin(), pipeline_ratios.end()));
    std::printf("ratio (d) record / raw (a):   median %.3f (min %.3f, max %.3f; target 0.8)\n", median(record_ratios),
                *std::min_element(record_ratios.begin(), record_ratios.end()),
                *std::max_element(record_ratios.begin(), record_ratios.end()));
    std::printf("    the same without any effect (the floor): median %.3f\n", median(floor_ratios));
    std::printf("against (a'), the caster's packing: (c) %.3f, (d) %.3f (medians)\n", median(pipeline_quad_ratios),
                median(record_quad_ratios));
    // What no effect chain can go above: the caster alone (the rays and their hits, no effect, no
    // encoding) and the floor (record without any effect).
    std::printf("    ColumnCaster alone %.3f, the floor (record, no effect) %.3f (medians)\n",
                median(caster_quad_ratios), median(floor_quad_ratios));
  }
}

// Effect chains on the same sensor, scene and rays, (c) / (a) each, from each pose: none (what
// the cast, the column bookkeeping and the encoding cost without any effect), the paper's
// linear law (the chain of profiles/os1-32-paper.json), the OS1-128 datasheet profile's, and every
// library effect on at once (mixed_pixels casts the columns beside each packet's block as well);
// then the datasheet chain less one effect at a time, what each of its effects costs (an effect
// that others need, radiometry, stays).
void chain_ratios(const Setup& s, const Scenario& scenario, int frames, int threads, int repeats) {
  const nlohmann::json every = test::every_effect_chain(test::range_noise_of(s.profile.effects));
  std::vector<std::pair<std::string, nlohmann::json>> chains = {
      {"none (cast, encode: the floor)", nlohmann::json::array()},
      {"paper (os1-32-paper's chain)", load_profile("os1-32-paper").effects},
      {"datasheet (os1-128's chain)", s.profile.effects},
      {"every effect on", every},
  };
  for (size_t left_out = 0; left_out < s.profile.effects.size(); ++left_out) {
    nlohmann::json less = s.profile.effects;
    less.erase(left_out);
    const std::string name = "datasheet less " + s.profile.effects[left_out].at("name").get<std::string>();
    try {
      (void)EffectChain::from_json(less, name);
      chains.emplace_back(name, less);
    } catch (const InputError&) {  // a later effect needs it
    }
  }
  WorkerPool pool(threads);
  std::printf("\neffect chains, %s: ratio (c) pipeline / raw (a), median of %d\n", scenario.name, repeats);
  std::vector<RTCRay16> rays;
  for (const auto& [name, effects] : chains) {
    ForwardModelSetup setup;
    setup.render = {
        s.metadata.beams, s.format(), s.profile.max_range_m, EffectChain::from_json(effects, name), 1, 1.0f};
    setup.pose_origin_s = scenario.poses->start_s();
    const ForwardModel model(s.scene, *scenario.poses, setup, pool);
    if (rays.empty()) rays = prebuilt_rays(s, *scenario.poses, frames, model.cast_range_m());
    std::vector<double> ratios;
    for (int r = 0; r < repeats; ++r) {
      const Rate a = raw_packets(s, rays, threads);
      ratios.push_back(pipeline(s, model, frames, threads).pixels.wall_per_s / a.wall_per_s);
    }
    std::printf("  %-38s %.3f (min %.3f, max %.3f)\n", name.c_str(), median(ratios),
                *std::min_element(ratios.begin(), ratios.end()), *std::max_element(ratios.begin(), ratios.end()));
  }
}

}  // namespace

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 20;
  const int threads_arg = argc > 2 ? std::atoi(argv[2]) : 0;
  const int repeats = argc > 3 ? std::atoi(argv[3]) : 5;
  const std::string only = argc > 4 ? argv[4] : "all";
  const int threads = threads_arg > 0 ? threads_arg : static_cast<int>(std::thread::hardware_concurrency());
  const Setup s;
  std::printf("OS1-128 2048x10, scenes/plant.glb (%zu triangles), %d frames, %d threads, %d repeats\n",
              s.scene.triangle_count(), frames, threads, repeats);
  const Scenario scenarios[] = {
      {"drone (scenes/plant_inspection.tum)",
       std::make_unique<TrajectoryPoses>(Trajectory::load_tum(kSource / "scenes/plant_inspection.tum"))},
      {"ground (pose \"15 9 1.7 0 0 0 1\")", std::make_unique<StaticPose>(parse_pose(kGroundPose))},
  };
  const std::string pose = argc > 5 ? argv[5] : "both";
  for (const Scenario& scenario : scenarios) {
    if (pose == "both" || std::string(scenario.name).starts_with(pose))
      run_scenario(s, scenario, frames, threads, repeats, only);
  }
  if (only != "all") return 0;
  for (const Scenario& scenario : scenarios) {
    if (pose == "both" || std::string(scenario.name).starts_with(pose))
      chain_ratios(s, scenario, frames, threads, repeats);
  }
  return 0;
}
