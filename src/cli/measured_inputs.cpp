// Turning the flags that name a measured capture into its pixel table, for compare and fit.
#include "cli/measured_inputs.h"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>

#include <unistd.h>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "lidartwin/analysis/static_table.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/pcap/osf.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin::cli {
namespace {

namespace fs = std::filesystem;

// A `record` output directory stands for its capture, metadata and ground-truth poses.
struct Inputs {
  fs::path capture, metadata, pose;
};
Inputs resolve_inputs(const MeasuredFlags& flags) {
  Inputs in{flags.capture, flags.metadata, flags.pose};
  if (fs::is_directory(in.capture)) {
    const fs::path dir = in.capture;
    in.capture = dir / "capture.pcap";
    if (in.metadata.empty()) in.metadata = dir / "metadata.json";
    // Its ground truth, but not for --map, which places the frames itself unless --pose says how.
    if (in.pose.empty() && !flags.map_mode && fs::exists(dir / "poses.tum")) in.pose = dir / "poses.tum";
  }
  if (!fs::is_regular_file(in.capture)) throw InputError("--capture " + in.capture.string() + ": no such capture file");
  // An OSF recording carries its sensor's metadata; a --metadata given beside it wins.
  if (read_as_osf(in.capture)) {
    if (!in.metadata.empty()) {
      std::fprintf(stderr, "note: --metadata %s replaces the sensor metadata stored in the OSF file %s\n",
                   in.metadata.string().c_str(), in.capture.string().c_str());
    }
  } else if (in.metadata.empty()) {
    throw InputError("give --metadata (the capture's sensor metadata JSON)");
  }
  if (flags.static_mode) return {in.capture, in.metadata, {}};
  if (flags.map_mode) return in;  // --pose optional: without it the frames are registered
  if (flags.scene.empty()) {
    throw InputError(
        "give --scene (the glTF scene of the measured place), or --map (a moving sensor, no scene), or --static "
        "(a motionless one)");
  }
  if (in.pose.empty()) {
    throw InputError("give --pose (a TUM file: one line for a static sensor, or a trajectory)");
  }
  return in;
}

// One TUM line: a static sensor, any time. More: the trajectory, only over the times it covers.
std::unique_ptr<PoseSource> load_measured_poses(const fs::path& path) {
  Trajectory trajectory = [&] {
    try {
      return Trajectory::load_tum(path, /*loop=*/false);
    } catch (const InputError& e) {
      throw InputError(std::string("--pose: ") + e.what());
    }
  }();
  if (trajectory.samples().size() == 1) return std::make_unique<StaticPose>(trajectory.samples().front().pose);
  // Pad by a microsecond: pcap and TUM times are written to that precision.
  const PoseSpan span{trajectory.start_s() - 1e-6, trajectory.start_s() + trajectory.duration_s() + 1e-6};
  return std::make_unique<TrajectoryPoses>(std::move(trajectory), span);
}

// The capture beside the scene: its beams cast at each column's time and pose (corrected first,
// with --refine-pose).
struct SceneComparison {
  PixelTable table;
  std::optional<PoseRefinement> refinement;
  std::vector<std::string> material_names;  // by Embree geometry id, the table's material
};
SceneComparison scene_table(const MeasuredFlags& flags, const Inputs& in, const MeasuredCapture& capture,
                            const EffectChain& chain, const SensorProfile& profile, Steps& steps) {
  const std::unique_ptr<PoseSource> measured = load_measured_poses(in.pose);
  steps.start("loading the scene");
  const Scene scene = Scene::load(flags.scene);
  steps.done();
  SceneComparison out;
  for (unsigned g = 0; g < scene.geometry_count(); ++g) out.material_names.push_back(scene.material(g).name);
  std::unique_ptr<PoseSource> corrected;
  if (flags.refine_pose) {
    steps.start("registering the measured points to the scene");
    RefineOptions options;
    options.max_range_m = profile.max_range_m;
    out.refinement = refine_pose(capture, scene, *measured, flags.time_offset_s, options);
    corrected = std::make_unique<CorrectedPoses>(*measured, out.refinement->correction);
    steps.done();
  }
  const PoseSource& poses = corrected ? *corrected : *measured;
  steps.start("casting the capture's beams and predicting every pixel");
  WorkerPool pool(flags.threads);
  PixelTableSetup setup{capture, scene, poses, flags.time_offset_s, chain, profile.max_range_m};
  setup.progress = [&steps](double fraction) {
    steps.progress("casting the capture's beams and predicting every pixel", fraction);
  };
  out.table = build_pixel_table(setup, pool);
  steps.done();
  if (std::ranges::none_of(out.table.ideal_range_m, [](float r) { return r > 0.0f; })) {
    throw InputError(
        fmt::format("--scene {} with --pose {}: no beam of the capture meets a surface of the scene (is "
                    "the pose in the scene's world frame, Z up, and inside its bounds?)",
                    flags.scene, in.pose.string()));
  }
  return out;
}

// Map mode: the frames placed by --pose or registered to each other, each return against the
// surface the other frames saw.
void map_table(const MeasuredFlags& flags, const Inputs& in, Measured& out, const EffectChain& chain,
               const SensorProfile& profile, Steps& steps) {
  WorkerPool pool(flags.threads);
  const bool within_frame = flags.within_frame || out.capture.frames.size() == 1;
  if (within_frame && !flags.within_frame) {
    std::fprintf(stderr,
                 "note: %s holds one frame: each return is compared with a surface fitted to the same frame's "
                 "returns around it, itself left out (--within-frame)\n",
                 in.capture.string().c_str());
  }
  std::unique_ptr<PoseSource> poses;
  if (!in.pose.empty()) {
    poses = load_measured_poses(in.pose);
  } else if (within_frame) {
    // A patch spans columns well under a millisecond apart: the frame's own motion does not show.
    poses = std::make_unique<StaticPose>(Pose{});
  } else {
    steps.start("registering the frames to each other");
    RegistrationOptions options;
    options.max_range_m = profile.max_range_m;
    out.inputs.registration = register_frames(out.capture, pool, options);
    const Trajectory& trajectory = out.inputs.registration->trajectory;
    const PoseSpan span{trajectory.start_s(), trajectory.start_s() + trajectory.duration_s()};
    poses = std::make_unique<TrajectoryPoses>(trajectory, span);
    steps.done();
  }
  const char* step = within_frame ? "fitting each return's surface from its frame's other returns and predicting it"
                                  : "fitting each return's surface from the other frames and predicting it";
  steps.start(step);
  MapTableSetup setup{out.capture, *poses, in.pose.empty() ? 0.0 : flags.time_offset_s, chain, profile.max_range_m};
  setup.within_frame = within_frame;
  setup.first_scored_frame = flags.skip_frames;
  setup.scored_frames = flags.frames;
  setup.progress = [&steps, step](double fraction) { steps.progress(step, fraction); };
  MapTable map = build_map_table(setup, pool);
  steps.done();
  out.table = std::move(map.table);
  out.inputs.map = map.excluded;
  out.inputs.map_within_frame = within_frame;
  // From here on the capture is the frames scored, as --frames and --skip-frames read it elsewhere.
  std::vector<BatchedFrame>& frames = out.capture.frames;
  const size_t end = flags.frames == 0 ? frames.size() : std::min(frames.size(), flags.skip_frames + flags.frames);
  frames.erase(frames.begin() + static_cast<std::ptrdiff_t>(end), frames.end());
  frames.erase(frames.begin(), frames.begin() + static_cast<std::ptrdiff_t>(flags.skip_frames));
  out.capture.skipped_frames = flags.skip_frames;
}

}  // namespace

void add_measured_options(CLI::App* sub, MeasuredFlags& flags) {
  sub->add_option("--capture", flags.capture,
                  "capture: a .pcap, an .osf recording (ouster-cli's), or a `lidartwin record` output directory")
      ->required();
  sub->add_option("--metadata", flags.metadata,
                  "the capture's sensor metadata JSON (FW 2.x/3.x); optional for an OSF file, which carries it");
  auto* scene = sub->add_option("--scene", flags.scene, "glTF scene (.glb/.gltf) of the measured place")
                    ->check(CLI::ExistingFile);
  auto* pose =
      sub->add_option(
             "--pose", flags.pose,
             "TUM file of world_from_sensor: one line for a static sensor, or a trajectory on the capture's clock")
          ->check(CLI::ExistingFile);
  auto* offset =
      sub->add_option("--time-offset", flags.time_offset_s, "seconds added to column timestamps to get pose times")
          ->capture_default_str();
  sub->add_option("--frames", flags.frames, "use at most this many frames (0 = all)")->capture_default_str();
  sub->add_option("--skip-frames", flags.skip_frames,
                  "leave out this many frames at the start (e.g. those a fit used: compare on held-out frames); "
                  "with --map the frames left out still make the reference surfaces")
      ->capture_default_str();
  sub->add_option("--threads", flags.threads, "threads (0 = all cores)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  auto* refine = sub->add_flag("--refine-pose", flags.refine_pose,
                               "register the measured points to the scene (point-to-plane) and correct the poses "
                               "first; the correction is printed and in report.json");
  auto* still = sub->add_flag("--static", flags.static_mode,
                              "no scene: a motionless sensor's repeated frames (2 or more), each pixel's temporal "
                              "spread and detection against the profile's prediction at its measured range")
                    ->excludes(scene)
                    ->excludes(pose)
                    ->excludes(offset)
                    ->excludes(refine);
  auto* map = sub->add_flag("--map", flags.map_mode,
                            "no scene: each return against a surface fitted to the other frames' points; the frames "
                            "are registered to each other (point to plane), or placed by --pose")
                  ->excludes(scene)
                  ->excludes(refine)
                  ->excludes(still);
  sub->add_flag("--within-frame", flags.within_frame,
                "with --map: each return against a surface fitted to its own frame's returns around it (itself "
                "left out), no registration; what --map does for a capture of one frame")
      ->needs(map);
}

Steps::Steps() : tty_(isatty(STDERR_FILENO) != 0) {}

// What the command printed on stdout goes first: piped into one log with stderr, a buffered report
// line would otherwise be cut in two by a step's line.
static void flush_stdout_before_a_step() {
  std::cout.flush();
  std::fflush(stdout);
}

void Steps::start(const char* what) {
  flush_stdout_before_a_step();
  what_ = what;
  printed_quarter_ = 0;
  if (tty_) std::fprintf(stderr, "\r%-60s", what);
  else std::fprintf(stderr, "%s ...\n", what);
  started_ = std::chrono::steady_clock::now();
}

void Steps::progress(const char* what, double fraction) const {
  if (!tty_) {
    const int quarter = static_cast<int>(fraction * 4);
    if (quarter <= printed_quarter_ || quarter >= 4) return;
    printed_quarter_ = quarter;
    std::fprintf(stderr, "%s: %d %%\n", what, 25 * quarter);
    return;
  }
  constexpr int kWidth = 20;
  const int filled = static_cast<int>(fraction * kWidth);
  std::fprintf(stderr, "\r%-60s [%s%s] %3.0f %%", what, std::string(static_cast<size_t>(filled), '=').c_str(),
               std::string(static_cast<size_t>(kWidth - filled), ' ').c_str(), 100.0 * fraction);
}

void Steps::note(const std::string& what) const {
  flush_stdout_before_a_step();
  if (tty_) std::fprintf(stderr, "\r%-60s", what.c_str());
  else std::fprintf(stderr, "%s\n", what.c_str());
}

void Steps::done() const {
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  if (tty_) std::fprintf(stderr, " %.1f s\n", seconds);
  else std::fprintf(stderr, "%s: done in %.1f s\n", what_.c_str(), seconds);
}

Measured measure(const MeasuredFlags& flags, const SensorProfile& profile, const EffectChain& chain, Steps& steps) {
  const Inputs in = resolve_inputs(flags);
  Measured out;
  steps.start("reading the capture");
  // Map mode reads every frame: those not scored (--skip-frames, beyond --frames) still make the
  // surfaces the scored ones are judged against.
  out.capture = flags.map_mode ? read_capture(in.capture, in.metadata)
                               : read_capture(in.capture, in.metadata, flags.frames, flags.skip_frames);
  steps.done();
  if (!out.capture.missing_fields.empty()) {
    std::fprintf(stderr, "note: %s holds no %s field; those channels are left zero\n", in.capture.string().c_str(),
                 fmt::format("{}", fmt::join(out.capture.missing_fields, ", ")).c_str());
  }
  if (out.capture.cut_short_record > 0) {
    std::fprintf(stderr,
                 "note: %s ends inside record %zu (a capture cut short while written); the frames before it are "
                 "read, and a frame it cuts is as complete as its packets\n",
                 in.capture.string().c_str(), out.capture.cut_short_record);
  }
  if (const size_t absent = columns_not_received(out.capture); absent > 0) {
    std::fprintf(stderr,
                 "note: %zu columns of the %zu frames read never arrived (packets lost, outside the azimuth window, "
                 "or after the recording stopped): left out, not scored as misses\n",
                 absent, out.capture.frames.size());
  }
  if (out.capture.lidar_streams > 1) {
    std::fprintf(stderr, "note: %s holds %zu lidar sensors; reading the first\n", in.capture.string().c_str(),
                 out.capture.lidar_streams);
  }
  if (flags.static_mode) {
    out.table = build_static_table({out.capture, chain, profile.max_range_m});
  } else if (flags.map_mode) {
    map_table(flags, in, out, chain, profile, steps);
  } else {
    SceneComparison compared = scene_table(flags, in, out.capture, chain, profile, steps);
    out.table = std::move(compared.table);
    out.inputs.pose_refinement = compared.refinement;
    out.inputs.material_names = std::move(compared.material_names);
  }
  const LidarDataFormat& format = out.capture.metadata.format;
  CompareInputs& inputs = out.inputs;
  inputs.capture = in.capture.string();
  inputs.metadata = in.metadata.empty() ? "(stored in the OSF capture)" : in.metadata.string();
  inputs.scene = flags.scene;
  inputs.pose = in.pose.string();
  inputs.static_mode = flags.static_mode;
  inputs.map_mode = flags.map_mode;
  inputs.time_offset_s = flags.time_offset_s;
  inputs.frames = out.capture.frames.size();
  inputs.skipped_frames = out.capture.skipped_frames;
  inputs.lidar_mode = to_string(LidarMode{format.columns_per_frame, format.fps});
  inputs.udp_profile_lidar = to_string(format.udp_profile_lidar);
  inputs.missing_fields = out.capture.missing_fields;
  inputs.columns_not_received = columns_not_received(out.capture);
  return out;
}

}  // namespace lidartwin::cli
