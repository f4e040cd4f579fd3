// `lidartwin compare`: a measured capture against the model of a profile, pixel by pixel, and a
// report of where the model fails (DIR/report.json, DIR/pixels.npz, DIR/report.html).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include <unistd.h>

#include <fmt/format.h>

#include "cli/command.h"
#include "cli/serve_inputs.h"
#include "lidartwin/analysis/compare_report.h"
#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/pixel_table.h"
#include "lidartwin/analysis/pose_refinement.h"
#include "lidartwin/analysis/static_table.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin::cli {
namespace {

namespace fs = std::filesystem;

struct CompareFlags {
  std::string capture;
  std::string metadata;
  std::string scene;
  std::string pose;
  std::string profile;
  std::string out;
  double time_offset_s = 0.0;
  size_t frames = 0;
  double alpha = 0.01;
  uint64_t seed = 0;
  int threads = 0;
  size_t show = 10;
  bool plots = true;
  bool static_mode = false;
  bool refine_pose = false;
  bool diagnose = false;
};

// A `record` output directory stands for its capture, metadata and ground-truth poses.
struct Inputs {
  fs::path capture, metadata, pose;
};
Inputs resolve_inputs(const CompareFlags& flags) {
  Inputs in{flags.capture, flags.metadata, flags.pose};
  if (fs::is_directory(in.capture)) {
    const fs::path dir = in.capture;
    in.capture = dir / "capture.pcap";
    if (in.metadata.empty()) in.metadata = dir / "metadata.json";
    if (in.pose.empty() && fs::exists(dir / "poses.tum")) in.pose = dir / "poses.tum";
  }
  if (!fs::is_regular_file(in.capture)) throw InputError("--capture " + in.capture.string() + ": no such capture file");
  if (in.metadata.empty()) throw InputError("compare: give --metadata (the capture's sensor metadata JSON)");
  if (flags.static_mode) return {in.capture, in.metadata, {}};
  if (flags.scene.empty())
    throw InputError("compare: give --scene (the glTF scene of the measured place), or --static");
  if (in.pose.empty()) {
    throw InputError("compare: give --pose (a TUM file: one line for a static sensor, or a trajectory)");
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

class Steps {
 public:
  void start(const char* what) {
    if (tty_) std::fprintf(stderr, "\r%-60s", what);
    started_ = std::chrono::steady_clock::now();
  }
  // "\r<what> [=========           ]  45 %" while a long step runs.
  void progress(const char* what, double fraction) const {
    if (!tty_) return;
    constexpr int kWidth = 20;
    const int filled = static_cast<int>(fraction * kWidth);
    std::fprintf(stderr, "\r%-60s [%s%s] %3.0f %%", what, std::string(static_cast<size_t>(filled), '=').c_str(),
                 std::string(static_cast<size_t>(kWidth - filled), ' ').c_str(), 100.0 * fraction);
  }
  void done() const {
    if (tty_) std::fprintf(stderr, " %.1f s\n", seconds());
  }
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count(); }

 private:
  bool tty_ = isatty(STDERR_FILENO) != 0;
  std::chrono::steady_clock::time_point started_;
};

// report.html comes from tools/compare-plots.py (Debian's python3 with numpy and matplotlib).
// Returns what happened, for the last lines of the run.
std::string write_plots(const fs::path& out) {
  const fs::path script = source_dir() / "tools" / "compare-plots.py";
  if (!fs::exists(script))
    return "report.html not written: " + script.string() + " not found (set LIDARTWIN_SOURCE_DIR)";
  const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  const fs::path log = out / "plots.log";
  const std::string command = python + " '" + script.string() + "' '" + out.string() + "' >'" + log.string() + "' 2>&1";
  const int status = std::system(command.c_str());
  if (status != 0) {
    return "report.html not written: " + script.filename().string() +
           " failed (needs python3 with numpy and "
           "matplotlib: tools/setup installs them; see " +
           log.string() + ")";
  }
  fs::remove(log);
  return "wrote " + (out / "report.html").string();
}

void write_json(const fs::path& path, const nlohmann::json& json) {
  std::ofstream out(path);
  out << json.dump(2) << "\n";
  if (!out) throw InputError(path.string() + ": write failed");
}

// The capture beside the scene: its beams cast at each column's time and pose (corrected first,
// with --refine-pose).
struct SceneComparison {
  PixelTable table;
  std::optional<PoseRefinement> refinement;
};
SceneComparison scene_table(const CompareFlags& flags, const Inputs& in, const MeasuredCapture& capture,
                            const EffectChain& chain, const SensorProfile& profile, Steps& steps) {
  const std::unique_ptr<PoseSource> measured = load_measured_poses(in.pose);
  steps.start("loading the scene");
  const Scene scene = Scene::load(flags.scene);
  steps.done();
  SceneComparison out;
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

nlohmann::json refinement_json(const PoseRefinement& r) {
  const Eigen::Vector3d t = r.correction.translation;
  const Eigen::Quaterniond q = r.correction.rotation;
  return {{"correction", {{"translation_m", {t.x(), t.y(), t.z()}}, {"rotation_xyzw", {q.x(), q.y(), q.z(), q.w()}}}},
          {"sensor_shift_m", {r.sensor_shift_m.x(), r.sensor_shift_m.y(), r.sensor_shift_m.z()}},
          {"rotation_deg", r.rotation_deg},
          {"rms_before_m", r.rms_before_m},
          {"rms_after_m", r.rms_after_m},
          {"points", r.points},
          {"iterations", r.iterations}};
}

int run_compare(const CompareFlags& flags) {
  const Inputs in = resolve_inputs(flags);
  const SensorProfile profile = load_profile(flags.profile);
  const EffectChain chain = EffectChain::from_json(profile.effects, "profile " + profile.name + ": /effects");
  Steps steps;
  steps.start("reading the capture");
  const MeasuredCapture capture = read_capture(in.capture, in.metadata, flags.frames);
  steps.done();
  SceneComparison compared;
  if (flags.static_mode) {
    compared.table = build_static_table({capture, chain, profile.max_range_m});
  } else {
    compared = scene_table(flags, in, capture, chain, profile, steps);
  }
  const PixelTable& table = compared.table;
  steps.start("scoring and binning");
  const PixelScores scores = score_pixels(table, flags.seed);
  MisfitOptions options;
  options.alpha = flags.alpha;
  options.static_mode = flags.static_mode;
  const Misfit misfit = find_misfit(table, scores, capture.frames.size(), options);
  steps.done();

  fs::create_directories(flags.out);
  nlohmann::json inputs = {
      {"capture", in.capture.string()},
      {"metadata", in.metadata.string()},
      {"scene", flags.scene},
      {"pose", in.pose.string()},
      {"static", flags.static_mode},
      {"profile", profile.name},
      {"time_offset_s", flags.time_offset_s},
      {"frames", capture.frames.size()},
      {"seed", flags.seed},
      {"lidar_mode", to_string(LidarMode{capture.metadata.format.columns_per_frame, capture.metadata.format.fps})},
      {"udp_profile_lidar", to_string(capture.metadata.format.udp_profile_lidar)}};
  if (compared.refinement) inputs["pose_refinement"] = refinement_json(*compared.refinement);
  nlohmann::json report = compare_report(misfit, inputs, flags.alpha);
  std::optional<Diagnosis> diagnosis;
  if (flags.diagnose) {
    steps.start("diagnosing: fitting each library effect the profile lacks");
    DiagnoseOptions diagnose_options;
    diagnose_options.alpha = flags.alpha;
    diagnosis = lidartwin::diagnose(table, chain, misfit, diagnose_options);
    report["diagnosis"] = diagnosis_json(*diagnosis);
    steps.done();
  }
  write_json(fs::path(flags.out) / "report.json", report);
  steps.start("writing pixels.npz");
  write_pixels_npz(fs::path(flags.out) / "pixels.npz", table, scores);
  steps.done();

  const MisfitSummary& s = misfit.summary;
  std::printf("compared %zu frames, %zu pixels (%zu returns) of %s with profile %s\n", s.frames, s.pixels, s.returns,
              in.capture.string().c_str(), profile.name.c_str());
  if (compared.refinement) {
    const PoseRefinement& r = *compared.refinement;
    std::printf(
        "pose refined on %zu points: sensor moved by (%+.4f, %+.4f, %+.4f) m, rotated by %.4f deg; "
        "point-to-plane RMS %.1f -> %.1f mm\n",
        r.points, r.sensor_shift_m.x(), r.sensor_shift_m.y(), r.sensor_shift_m.z(), r.rotation_deg,
        1000 * r.rms_before_m, 1000 * r.rms_after_m);
  }
  std::printf("NLL per pixel %.4f, expected %.4f +- %.4f if the model were true (%+.1f standard errors)\n",
              s.nll_per_pixel, s.nll_expected, s.nll_se,
              s.nll_se > 0 ? (s.nll_per_pixel - s.nll_expected) / s.nll_se : 0.0);
  std::printf("detection %.1f %% measured, %.1f %% predicted; range z: mean %+.3f, std %.3f; PIT uniform p = %.3g\n",
              100 * s.detection_measured, 100 * s.detection_predicted, s.z_mean, s.z_std, s.pit_uniformity_p);
  if (misfit.failing.empty()) {
    std::printf("no region fails at alpha %g (%zu tests, Bonferroni-corrected)\n", flags.alpha, s.tests);
  } else {
    std::printf("%zu failing regions at alpha %g (%zu tests, Bonferroni-corrected); worst first:\n",
                misfit.failing.size(), flags.alpha, s.tests);
    for (size_t i = 0; i < std::min(flags.show, misfit.failing.size()); ++i) {
      std::printf("  %2zu. [%s] %s\n", i + 1, misfit.failing[i].quantity.c_str(), misfit.failing[i].sentence.c_str());
    }
  }
  if (diagnosis) {
    std::printf("diagnosis on %zu pixels: %s\n", diagnosis->pixels, diagnosis->verdict.c_str());
    for (size_t i = 0; i < std::min<size_t>(diagnosis->ranked.size(), 5); ++i) {
      const Candidate& c = diagnosis->ranked[i];
      std::string params;
      for (const FittedParameter& p : c.params) params += fmt::format(" {}={:.4g}", p.name, p.value);
      std::printf("  %s (%s): delta BIC %+.1f, p %.2g;%s\n", c.effect.c_str(), c.catalogue.c_str(), c.delta_bic,
                  c.p_value, params.c_str());
    }
    for (const Candidate& c : diagnosis->selected) std::printf("  selected: %s\n", c.effect.c_str());
  }
  std::string plots = "report.html not written (--no-plots)";
  if (flags.plots) {
    steps.start("plotting report.html");
    plots = write_plots(flags.out);
    steps.done();
  }
  std::printf("wrote %s/report.json and %s/pixels.npz; %s\n", flags.out.c_str(), flags.out.c_str(), plots.c_str());
  return 0;
}

void setup_compare(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<CompareFlags>();
  CLI::App* sub = app.add_subcommand(
      "compare", "Compare a measured capture with a profile's model: DIR/report.json, DIR/pixels.npz");
  sub->add_option("--capture", flags->capture, "capture .pcap, or a `lidartwin record` output directory")->required();
  sub->add_option("--metadata", flags->metadata, "the capture's sensor metadata JSON (FW 2.x/3.x)");
  auto* scene = sub->add_option("--scene", flags->scene, "glTF scene (.glb/.gltf) of the measured place")
                    ->check(CLI::ExistingFile);
  auto* pose =
      sub->add_option(
             "--pose", flags->pose,
             "TUM file of world_from_sensor: one line for a static sensor, or a trajectory on the capture's clock")
          ->check(CLI::ExistingFile);
  sub->add_option("--profile", flags->profile, "profile whose effect chain is compared (name or .json)")->required();
  sub->add_option("--out", flags->out, "output directory (created)")->required();
  auto* offset =
      sub->add_option("--time-offset", flags->time_offset_s, "seconds added to column timestamps to get pose times")
          ->capture_default_str();
  sub->add_flag("--static", flags->static_mode,
                "no scene: a motionless sensor's repeated frames, each pixel's temporal spread and detection against "
                "the profile's prediction at its measured range")
      ->excludes(scene)
      ->excludes(pose)
      ->excludes(offset)
      ->excludes(sub->add_flag("--refine-pose", flags->refine_pose,
                               "register the measured points to the scene (point-to-plane) and correct the poses "
                               "before comparing; the correction is printed and in report.json"));
  sub->add_option("--frames", flags->frames, "compare at most this many frames (0 = all)")->capture_default_str();
  sub->add_option("--alpha", flags->alpha, "significance level, after correction for the number of tests")
      ->check(CLI::Range(1e-12, 0.5))
      ->capture_default_str();
  sub->add_option("--seed", flags->seed, "seed of the PIT's tie-breaking draws")->capture_default_str();
  sub->add_option("--threads", flags->threads, "threads (0 = all cores)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  sub->add_flag("!--no-plots", flags->plots, "skip report.html (tools/compare-plots.py)");
  sub->add_flag("--diagnose", flags->diagnose,
                "fit each library effect the profile lacks (maximum likelihood) and rank them: which is missing")
      ->excludes("--static");
  sub->callback([&run, flags] { run = [flags] { return run_compare(*flags); }; });
}

const RegisterCommand registered("compare", setup_compare);

}  // namespace
}  // namespace lidartwin::cli
