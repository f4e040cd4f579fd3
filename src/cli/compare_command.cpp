// `lidartwin compare`: a measured capture against the model of a profile, pixel by pixel, and a
// report of where the model fails (DIR/report.json, DIR/report.html; with --pixels DIR/pixels.npz).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "cli/atomic_output.h"
#include "cli/command.h"
#include "cli/measured_inputs.h"
#include "cli/parameter_text.h"
#include "cli/plot_script.h"
#include "cli/unit_twin.h"
#include "lidartwin/analysis/compare_report.h"
#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/unexplained.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin::cli {
namespace {

namespace fs = std::filesystem;

struct CompareFlags {
  MeasuredFlags measured;
  std::vector<std::string> profiles;
  std::string out;
  double alpha = 0.01;
  uint64_t seed = 0;
  size_t show = 10;
  bool plots = true;
  bool pixels = false;
  bool diagnose = false;
  bool keep_profile = false;
  bool refit_noise = false;
};

// The profiles to compare, each with its chain (a unit's metadata: its twin's chain).
struct Profiles {
  std::vector<SensorProfile> profiles;
  std::vector<EffectChain> chains;
};
Profiles load_profiles(const std::vector<std::string>& names) {
  Profiles out;
  for (const std::string& name : names) {
    out.profiles.push_back(load_sensor(name).profile);
    const SensorProfile& profile = out.profiles.back();
    out.chains.push_back(profile_chain(profile));
  }
  return out;
}

// Every profile scored on the same pixels (the waterfall); the misfit is the last one's, whose
// table and scores are returned (the first profile's table is the measured one, not copied).
struct Scored {
  PixelTable other;  // a later profile's predictions
  const PixelTable* table = nullptr;
  PixelScores scores;
};
void score_profiles(const CompareFlags& flags, const Measured& measured, const Profiles& p, CompareResult& result,
                    Scored& scored, Steps& steps) {
  MisfitOptions options;
  options.alpha = flags.alpha;
  scored.table = &measured.table;
  WorkerPool pool(flags.measured.threads);
  for (size_t k = 0; k < p.profiles.size(); ++k) {
    steps.start(p.profiles.size() > 1 ? "scoring and binning, profile by profile" : "scoring and binning");
    if (k > 0) {
      scored.other = repredicted(measured.table, p.chains[k], &pool);
      scored.table = &scored.other;
    }
    scored.scores = score_pixels(*scored.table, flags.seed, &pool);
    result.misfit = find_misfit(*scored.table, scored.scores, measured.capture.frames.size(), options);
    result.waterfall.push_back(
        waterfall_step(p.profiles[k].name, *scored.table, result.misfit, measured.inputs.material_names));
    steps.done();
  }
  note_waterfall(result.waterfall);
}

Diagnosis diagnose_last(const CompareFlags& flags, const PixelTable& table, const SensorProfile& profile,
                        const EffectChain& chain, const Misfit& misfit, Steps& steps) {
  steps.start("diagnosing: fitting each library effect the profile lacks");
  DiagnoseOptions options;
  options.alpha = flags.alpha;
  options.refit_profile = !flags.keep_profile;
  options.refit_range_noise = flags.refit_noise;
  options.datasheet_noise = datasheet_range_noise(profile.prod_line);
  WorkerPool pool(flags.measured.threads);
  options.pool = &pool;
  options.progress = [&steps](const std::string& what) { steps.note("diagnosing: " + what); };
  Diagnosis diagnosis = lidartwin::diagnose(table, chain, misfit, options);
  steps.done();
  return diagnosis;
}

// DIR/report.json, with --pixels DIR/pixels.npz (117 bytes a pixel: 380 MB for 50 frames of
// 64 x 1024) and, for registered frames, DIR/registered_poses.tum.
// Each output is written whole or not at all (write_atomically), report.json last: an earlier run's
// outputs are removed first (they describe another comparison), so a directory with a report.json
// holds a complete set, and one without it a run that failed (the error names the file).
void write_outputs(const CompareFlags& flags, const CompareResult& result, const Scored& scored, Steps& steps) {
  const fs::path out(flags.out);
  fs::create_directories(out);
  for (const char* earlier : {"report.json", "report.html", "pixels.npz", "registered_poses.tum"}) {
    fs::remove(out / earlier);
  }
  if (flags.pixels) {
    steps.start("writing pixels.npz");
    write_atomically(out / "pixels.npz",
                     [&](const fs::path& file) { write_pixels_npz(file, *scored.table, scored.scores); });
    steps.done();
  }
  if (result.inputs.registration) {
    write_atomically(out / "registered_poses.tum",
                     [&](const fs::path& file) { result.inputs.registration->trajectory.save_tum(file); });
  }
  write_json_atomically(out / "report.json", report_json(result));
}

// An argument as a POSIX shell reads it back: quoted where it holds anything but safe characters.
std::string shell_word(const std::string& word) {
  const bool safe = !word.empty() && std::all_of(word.begin(), word.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || std::string_view("/._-+=:,@%").find(c) != std::string::npos;
  });
  if (safe) return word;
  std::string out = "'";
  for (char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// The `fit` that applies what the diagnosis found to the compared profile, on the same capture:
// its replacements (--replace) and selected effects (--add), fitted again there. Empty when the
// diagnosis neither adds nor replaces anything.
// Where the diagnosis adds nothing but refits the profile's own effects on the range (a unit whose
// noise is tighter than the profile's), `fit --auto` makes that refit: a twin of this unit.
std::string next_fit_command(const CompareFlags& flags, const Diagnosis& diagnosis) {
  const bool refits = std::any_of(diagnosis.parameter_misfit.begin(), diagnosis.parameter_misfit.end(),
                                  [](const ParameterMisfit& m) { return m.channel == "range"; });
  const bool adds = !diagnosis.selected.empty() || !diagnosis.replace.empty();
  if (!adds && !refits) return "";
  const MeasuredFlags& m = flags.measured;
  std::string command = "lidartwin fit --capture " + shell_word(m.capture);
  const auto option = [&](const char* name, const std::string& value) {
    if (!value.empty()) command += fmt::format(" {} {}", name, shell_word(value));
  };
  option("--metadata", m.metadata);
  option("--scene", m.scene);
  option("--pose", m.pose);
  if (m.time_offset_s != 0.0) option("--time-offset", fmt::format("{}", m.time_offset_s));
  if (m.frames > 0) option("--frames", std::to_string(m.frames));
  if (m.skip_frames > 0) option("--skip-frames", std::to_string(m.skip_frames));
  if (m.static_mode) command += " --static";
  if (m.map_mode) command += " --map";
  if (m.within_frame) command += " --within-frame";
  if (m.refine_pose) command += " --refine-pose";
  option("--profile", flags.profiles.back());
  if (!adds) command += " --auto";
  for (const Replacement& r : diagnosis.replace) option("--replace", r.effect + "=" + r.with.effect);
  for (const Candidate& c : diagnosis.selected) option("--add", c.effect);
  if (flags.refit_noise) command += " --refit-noise";
  option("--out", (fs::path(flags.out) / "fitted.json").string());
  return command;
}

void print_inputs(const CompareFlags& flags, const CompareInputs& in) {
  if (in.registration) {
    const FrameRegistration& r = *in.registration;
    std::printf(
        "frames registered to each other: the sensor travelled %.2f m; %zu point-to-plane pairs, RMS %.1f mm after "
        "%d iterations (%s/registered_poses.tum)\n",
        r.path_length_m, r.pairs, 1000 * r.rms_m, r.iterations, flags.out.c_str());
  }
  if (in.map) {
    const MapExclusions& x = *in.map;
    const auto share = [&](size_t n) { return x.returns > 0 ? 100.0 * static_cast<double>(n) / x.returns : 0.0; };
    const char* around = in.map_within_frame ? "other returns of their frame" : "other frames";
    std::printf(
        "map%s: %zu of %zu returns compared (%.1f %%); left out: %zu beside depth steps, %zu with too few points of "
        "%s around them, %zu on no smooth surface, %zu off the surface %s saw, %zu at grazing incidence\n",
        in.map_within_frame ? " (within each frame)" : "", x.compared, x.returns, share(x.compared), x.edge,
        x.unsupported, around, x.not_surface, x.off_surface, in.map_within_frame ? "its neighbours" : "other frames",
        x.grazing);
  }
  if (in.pose_refinement) {
    const PoseRefinement& r = *in.pose_refinement;
    std::printf(
        "pose refined on %zu points: sensor moved by (%+.4f, %+.4f, %+.4f) m, rotated by %.4f deg; "
        "point-to-plane RMS %.1f -> %.1f mm\n",
        r.points, r.sensor_shift_m.x(), r.sensor_shift_m.y(), r.sensor_shift_m.z(), r.rotation_deg,
        1000 * r.rms_before_m, 1000 * r.rms_after_m);
  }
}

void print_misfit(const CompareFlags& flags, const Misfit& misfit, const WaterfallStep& parts,
                  const std::vector<std::string>& material_names) {
  const MisfitSummary& s = misfit.summary;
  const double excess = s.nll_se > 0 ? (s.nll_per_pixel - s.nll_expected) / s.nll_se : 0.0;
  std::printf("NLL per pixel %.4f, expected %.4f +- %.4f if the model were true (%+.1f standard errors)\n",
              s.nll_per_pixel, s.nll_expected, s.nll_se, excess);
  // The excess averages over every pixel: where the model is too wide a pixel's NLL is below its
  // expectation, where too narrow above, and the two cancel. Its two parts, and the failing
  // regions, cannot.
  if (!misfit.failing.empty()) {
    std::printf(
        "  (an average that can cancel: over range x reflectivity bins, %+.4f nats a pixel where the NLL lies below "
        "the model's expectation, too wide or too unsure there, and %+.4f where above, too narrow or too sure; the "
        "%zu failing regions below say where it errs)\n",
        parts.excess_below, parts.excess_above, misfit.failing.size());
  }
  std::printf("detection %.1f %% measured, %.1f %% predicted; range z: mean %+.3f, std %.3f; PIT uniform p = %.3g\n",
              100 * s.detection_measured, 100 * s.detection_predicted, s.z_mean, s.z_std, s.pit_uniformity_p);
  if (misfit.failing.empty()) {
    std::printf("no region fails at alpha %g (%zu tests, Bonferroni-corrected)\n", flags.alpha, s.tests);
    return;
  }
  const std::vector<FailingRun> runs = failing_runs(misfit, material_names);
  std::printf(
      "%zu failing regions at alpha %g (%zu tests, Bonferroni-corrected), %zu after merging neighbouring bins; "
      "those whose misfit their feature explains most first:\n",
      misfit.failing.size(), flags.alpha, s.tests, runs.size());
  for (size_t i = 0; i < std::min(flags.show, runs.size()); ++i) {
    std::printf("  %2zu. [%s] %s\n", i + 1, runs[i].quantity.c_str(), runs[i].sentence.c_str());
  }
}

// "divergence_rad = 0.00192, 95 %: 0.00191 .. 0.00193 (robust 0.00185 .. 0.00199)".
std::string interval_text(const FittedParameter& p) {
  std::string text = fmt::format("{} = {:.4g}, 95 %: {:.4g} .. {:.4g}", p.name, p.value, p.ci95_lo, p.ci95_hi);
  if (!std::isnan(p.robust_lo)) text += fmt::format(" (robust {:.4g} .. {:.4g})", p.robust_lo, p.robust_hi);
  if (const std::string note = bound_note(p); !note.empty()) text += " [" + note + ": the data does not fix it]";
  return text;
}

void print_diagnosis(const Diagnosis& diagnosis, const std::string& next_command) {
  std::printf("diagnosis on %zu pixels: %s\n", diagnosis.pixels, diagnosis.verdict.c_str());
  for (const ParameterMisfit& m : diagnosis.parameter_misfit) {
    std::string changes;
    for (const FittedParameter& p : m.refit.params) {
      const auto old =
          std::find_if(m.old_values.begin(), m.old_values.end(), [&](const auto& o) { return o.first == p.name; });
      changes += fmt::format(" {} {:.4g} -> {:.4g}", p.name, old == m.old_values.end() ? 0.0 : old->second, p.value);
    }
    std::printf("  refitted %s (%s channel): delta BIC %+.1f;%s\n", m.refit.effect.c_str(), m.channel.c_str(),
                m.refit.delta_bic, changes.c_str());
  }
  for (size_t i = 0; i < std::min<size_t>(diagnosis.ranked.size(), 5); ++i) {
    const Candidate& c = diagnosis.ranked[i];
    // Each ranked candidate is fitted alone against the profile; a selected one's delta BIC is given
    // those selected before it, which is smaller where they explain some of the same misfit.
    std::printf("  %s (%s): delta BIC %+.1f alone, p %.2g;%s\n", c.effect.c_str(), c.catalogue.c_str(), c.delta_bic,
                c.p_value, parameter_values_text(c.params).c_str());
  }
  for (const Replacement& r : diagnosis.replace) std::printf("  replace: %s\n", r.sentence.c_str());
  for (const Candidate& c : diagnosis.selected) {
    std::printf("  selected: %s (delta BIC %+.1f given the effects selected before it)\n", c.effect.c_str(),
                c.delta_bic);
    const std::vector<FittedParameter> shown = parameters_to_show(c.params, 8);
    for (const FittedParameter& p : shown) std::printf("    %s\n", interval_text(p).c_str());
    if (shown.size() < c.params.size()) {
      std::printf("    (the %zu strongest of %zu parameters; report.json has them all)\n", shown.size(),
                  c.params.size());
    }
  }
  for (const SharedMisfit& shared : diagnosis.shared) std::printf("  %s\n", shared.sentence.c_str());
  for (const NotSelected& n : diagnosis.not_selected) std::printf("  %s\n", n.sentence.c_str());
  for (const UnexplainedMisfit& u : diagnosis.unexplained) std::printf("  unexplained: %s\n", u.sentence.c_str());
  if (!diagnosis.intervals_caveat.empty()) std::printf("  %s\n", diagnosis.intervals_caveat.c_str());
  if (!diagnosis.remaining_note.empty()) std::printf("  %s\n", diagnosis.remaining_note.c_str());
  if (!next_command.empty()) std::printf("  next: %s\n", next_command.c_str());
}

void print_waterfall(const std::vector<WaterfallStep>& waterfall) {
  std::printf("the error across the profiles (same pixels):\n  %-24s %12s %10s %10s %8s %10s %8s\n", "profile",
              "NLL/pixel", "excess SE", "bias RMS", "spread", "det. loss", "failing");
  for (const WaterfallStep& w : waterfall) {
    std::printf("  %-24s %12.4f %+10.1f %8.1f mm %8.2f %10.4f %8zu\n", w.profile.c_str(), w.nll_per_pixel,
                w.nll_se > 0 ? (w.nll_per_pixel - w.nll_expected) / w.nll_se : 0.0, 1000 * w.bias_rms_m,
                w.spread_ratio_median, w.detection_log_loss, w.failing);
  }
  for (const WaterfallStep& w : waterfall) {
    if (!w.note.empty()) std::printf("  %s\n", w.note.c_str());
  }
}

int run_compare(const CompareFlags& flags) {
  const Profiles p = load_profiles(flags.profiles);
  Steps steps;
  const Measured measured = measure(flags.measured, p.profiles.front(), p.chains.front(), steps);
  CompareResult result;
  result.inputs = measured.inputs;
  result.inputs.seed = flags.seed;
  result.inputs.profile = p.profiles.back().name;  // the report is of the last profile
  result.prod_line = p.profiles.back().prod_line;
  result.unit_range_spread = p.profiles.back().unit_range_spread;
  result.unit_to_unit_source = p.profiles.back().unit_to_unit_source;
  result.alpha = flags.alpha;
  Scored scored;
  score_profiles(flags, measured, p, result, scored, steps);
  // What each failing quantity follows, correlated features partialled out: the runs lead with it.
  if (!result.misfit.failing.empty()) {
    steps.start("finding what each failing quantity follows");
    find_causes(*scored.table, scored.scores, result.misfit, flags.alpha);
    steps.done();
  }
  result.residuals = residual_histograms(*scored.table, scored.scores);
  if (!result.misfit.failing.empty()) result.image = range_image(*scored.table, scored.scores, result.misfit);
  if (flags.diagnose) {
    // A unit whose spread is tighter or wider than the profile's nearly everywhere: its own noise
    // law is what to fit first, so the diagnosis refits the law's sigmas (--refit-noise) and the
    // next command carries it.
    CompareFlags diagnosed = flags;
    diagnosed.refit_noise = flags.refit_noise || !unit_spread_words(result).empty();
    result.diagnosis =
        diagnose_last(diagnosed, *scored.table, p.profiles.back(), p.chains.back(), result.misfit, steps);
    result.next_command = next_fit_command(diagnosed, *result.diagnosis);
  }
  write_outputs(flags, result, scored, steps);

  const MisfitSummary& s = result.misfit.summary;
  std::printf("%s\n", verdict_sentence(result).c_str());
  std::printf("compared %zu frames, %zu pixels (%zu returns) of %s with profile %s\n", s.frames, s.pixels, s.returns,
              result.inputs.capture.c_str(), result.inputs.profile.c_str());
  print_inputs(flags, result.inputs);
  print_misfit(flags, result.misfit, result.waterfall.back(), result.inputs.material_names);
  if (result.diagnosis) print_diagnosis(*result.diagnosis, result.next_command);
  if (result.waterfall.size() > 1) print_waterfall(result.waterfall);
  std::string plots = "report.html not written (--no-plots)";
  if (flags.plots) {
    steps.start("plotting report.html");
    plots = run_plot_script("compare-plots.py", flags.out, "report.html");
    steps.done();
  }
  std::printf("wrote %s/report.json%s; %s\n", flags.out.c_str(),
              flags.pixels ? (" and " + flags.out + "/pixels.npz").c_str() : "", plots.c_str());
  return 0;
}

void setup_compare(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<CompareFlags>();
  CLI::App* sub = app.add_subcommand(
      "compare",
      "Compare a measured capture with a profile's model: DIR/report.json, DIR/report.html (--pixels: "
      "DIR/pixels.npz)");
  add_measured_options(sub, flags->measured);
  sub->add_option("--profile", flags->profiles,
                  "profile whose effect chain is compared (name or .json); several: a waterfall of the error "
                  "across them, the report of the last")
      ->required();
  sub->add_option("--out", flags->out, "output directory (created)")->required();
  sub->add_option("--alpha", flags->alpha, "significance level, after correction for the number of tests")
      ->check(CLI::Range(1e-12, 0.5))
      ->capture_default_str();
  sub->add_option("--seed", flags->seed, "seed of the PIT's tie-breaking draws")->capture_default_str();
  sub->add_flag("!--no-plots", flags->plots, "skip report.html (tools/compare-plots.py)");
  sub->add_flag("--pixels", flags->pixels,
                "also write DIR/pixels.npz, every pixel's measurement, prediction and score for numpy (117 bytes a "
                "pixel)");
  sub->add_flag("--diagnose", flags->diagnose,
                "fit each library effect the profile lacks (maximum likelihood) and rank them: which is missing");
  sub->add_flag("--keep-profile", flags->keep_profile,
                "with --diagnose: keep the profile's own effects as they are (neither refit their parameters nor "
                "replace its noise law)")
      ->needs("--diagnose");
  sub->add_flag("--refit-noise", flags->refit_noise,
                "with --diagnose: refit the profile's range noise sigma(r) (its knots' sigmas) among its own effects")
      ->needs("--diagnose")
      ->excludes("--keep-profile");
  sub->callback([&run, flags] { run = [flags] { return run_compare(*flags); }; });
}

const RegisterCommand registered_compare("compare", setup_compare);

}  // namespace
}  // namespace lidartwin::cli
