// `lidartwin ape`: the absolute pose error of an odometry/SLAM trajectory against ground truth
// (e.g. `record`'s poses.tum), as evo's evo_ape computes it: the paper's Table II experiment.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/atomic_output.h"
#include "cli/command.h"
#include "cli/plot_script.h"
#include "lidartwin/error.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/trajectory_error.h"

namespace lidartwin::cli {
namespace {

namespace fs = std::filesystem;

struct ApeFlags {
  std::string reference;
  std::string estimate;
  std::string align = "se3";
  double max_diff_s = 0.01;
  double offset_s = 0.0;
  std::string out;
};

std::vector<StampedPose> load(const std::string& flag, const std::string& path) {
  try {
    return Trajectory::load_tum(path, /*loop=*/false).samples();
  } catch (const InputError& e) {
    throw InputError(flag + ": " + e.what());
  }
}

int run_ape(const ApeFlags& flags) {
  ApeOptions options;
  options.max_time_difference_s = flags.max_diff_s;
  options.time_offset_s = flags.offset_s;
  options.alignment = flags.align == "none"   ? Alignment::kNone
                      : flags.align == "sim3" ? Alignment::kSim3
                                              : Alignment::kSe3;
  const ApeResult r =
      absolute_pose_error(load("--reference", flags.reference), load("--estimate", flags.estimate), options);
  std::printf("APE w.r.t. translation part (m), %s alignment, %zu pose pairs\n", flags.align.c_str(), r.pairs);
  std::printf(
      "       max  %10.6f\n      mean  %10.6f\n    median  %10.6f\n       min  %10.6f\n      rmse  %10.6f\n"
      "       std  %10.6f\n",
      r.max_m, r.mean_m, r.median_m, r.min_m, r.rmse_m, r.std_m);
  if (flags.align == "sim3") std::printf("     scale  %10.6f\n", r.scale);
  if (flags.out.empty()) return 0;
  fs::create_directories(flags.out);
  const Eigen::Vector3d t = r.alignment.translation;
  const Eigen::Quaterniond q = r.alignment.rotation;
  const nlohmann::json json = {
      {"reference", flags.reference},
      {"estimate", flags.estimate},
      {"alignment", flags.align},
      {"pairs", r.pairs},
      {"rmse_m", r.rmse_m},
      {"mean_m", r.mean_m},
      {"median_m", r.median_m},
      {"std_m", r.std_m},
      {"min_m", r.min_m},
      {"max_m", r.max_m},
      {"scale", r.scale},
      {"reference_from_estimate",
       {{"translation_m", {t.x(), t.y(), t.z()}}, {"rotation_xyzw", {q.x(), q.y(), q.z(), q.w()}}}},
      {"times_s", r.times_s},
      {"errors_m", r.errors_m}};
  write_json_atomically(fs::path(flags.out) / "ape.json", json);
  std::printf("wrote %s; %s\n", (fs::path(flags.out) / "ape.json").c_str(),
              run_plot_script("ape-plot.py", flags.out, "ape.png").c_str());
  return 0;
}

void setup_ape(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<ApeFlags>();
  CLI::App* sub = app.add_subcommand("ape", "Absolute pose error of a trajectory against ground truth (TUM), as evo");
  sub->add_option("--reference", flags->reference, "ground truth TUM file (e.g. record's poses.tum)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--estimate", flags->estimate, "estimated trajectory, TUM")->required()->check(CLI::ExistingFile);
  sub->add_option("--align", flags->align, "alignment before the errors: se3 (evo -a), sim3 (evo -as), none")
      ->check(CLI::IsMember({"se3", "sim3", "none"}))
      ->capture_default_str();
  sub->add_option("--max-diff", flags->max_diff_s, "largest timestamp difference of a pair, s (evo --t_max_diff)")
      ->check(CLI::Range(0.0, 10.0))
      ->capture_default_str();
  sub->add_option("--time-offset", flags->offset_s, "added to the estimate's stamps, s (evo --t_offset)")
      ->capture_default_str();
  sub->add_option("--out", flags->out, "directory for ape.json and ape.png (the error over time)");
  sub->callback([&run, flags] { run = [flags] { return run_ape(*flags); }; });
}

const RegisterCommand registered_ape("ape", setup_ape);

}  // namespace
}  // namespace lidartwin::cli
