// `lidartwin fit`: a new profile with effects added to the measured capture's profile, or put in
// place of its own (its noise law replaced by another form), their parameters fitted by maximum
// likelihood on it (the diagnosis' fits), written as a profile file that record, serve and compare
// read as they are. The fitted values and their 95 % intervals go into the profile's "fit"
// section, next to the effects.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "cli/atomic_output.h"
#include "cli/command.h"
#include "cli/measured_inputs.h"
#include "cli/parameter_text.h"
#include "cli/unit_twin.h"
#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/misfit.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin::cli {
namespace {

namespace fs = std::filesystem;

struct FitFlags {
  MeasuredFlags measured;
  std::string profile;
  std::vector<std::string> add;
  std::vector<std::string> replace;  // OLD=NEW
  bool automatic = false;
  bool refit_noise = false;
  std::string out;
  double alpha = 0.01;
};

// A fitted effect in the "fit" section: its delta BIC, p-value (where nested) and parameters.
nlohmann::json note(const Candidate& c) {
  nlohmann::json params = nlohmann::json::object();
  for (const FittedParameter& p : c.params) {
    params[p.name] = {{"value", p.value}, {"ci95", {p.ci95_lo, p.ci95_hi}}};
    if (!std::isnan(p.robust_lo)) params[p.name]["ci95_robust"] = {p.robust_lo, p.robust_hi};
    if (const std::string bound = bound_note(p); !bound.empty()) params[p.name]["bound"] = bound;
  }
  return {{"effect", c.effect},
          {"catalogue", c.catalogue},
          {"delta_bic", c.delta_bic},
          {"p_value", c.p_value},
          {"params", params}};
}

struct Fitted {
  EffectChain chain;
  std::vector<Candidate> refits;  // the profile's own effects refitted (radiometry, noise)
  std::vector<Replacement> replaced;
  std::vector<Candidate> added;
};

nlohmann::json fit_notes(const Fitted& fitted, const Measured& measured, size_t pixels) {
  nlohmann::json effects = nlohmann::json::array();
  for (const Candidate& c : fitted.refits) effects.push_back(note(c));
  for (const Replacement& r : fitted.replaced) {
    nlohmann::json entry = note(r.with);
    entry.erase("p_value");  // not nested in the law it replaces: BIC alone
    entry["replaces"] = r.effect;
    effects.push_back(entry);
  }
  for (const Candidate& c : fitted.added) effects.push_back(note(c));
  return {{"comment", "written by lidartwin fit: effects added or replaced and fitted by maximum likelihood"},
          {"capture", measured.inputs.capture},
          {"frames", measured.inputs.frames},
          {"pixels", pixels},
          {"effects", effects}};
}

// Where a fitted effect's parameters came from, in the words a profile's "source" uses.
std::string fit_source(const Candidate& c, const Measured& measured, size_t pixels) {
  const CompareInputs& in = measured.inputs;
  const PixelTable::Reference reference = measured.table.reference;
  const std::string mode = reference == PixelTable::Reference::kMap            ? " --map"
                           : reference == PixelTable::Reference::kTemporalMean ? " --static"
                                                                               : "";
  std::string out =
      fmt::format("lidartwin fit{} on {} (frames {}-{}, {} pixels):", mode, fs::path(in.capture).filename().string(),
                  in.skipped_frames, in.skipped_frames + in.frames - 1, pixels);
  constexpr size_t kShown = 6;  // of a table (E10's per beam): the effect itself holds every value
  for (const FittedParameter& p : parameters_to_show(c.params, kShown)) {
    out += fmt::format(" {} {:.4g} (95 %: {:.4g}-{:.4g})", p.name, p.value, p.ci95_lo, p.ci95_hi);
  }
  if (c.params.size() > kShown) out += fmt::format(" (the {} strongest of {} parameters)", kShown, c.params.size());
  return out + fmt::format(", delta BIC {:+.0f}", c.delta_bic);
}

// Each effect's "source": this fit's for what it fitted, the profile's own for what it kept.
void attach_sources(nlohmann::json& effects, const nlohmann::json& before, const Fitted& fitted,
                    const Measured& measured, size_t pixels) {
  std::map<std::string, std::string> fitted_now;
  for (const Candidate& c : fitted.refits) fitted_now[c.effect] = fit_source(c, measured, pixels);
  for (const Replacement& r : fitted.replaced) {
    fitted_now[r.with.effect] = fit_source(r.with, measured, pixels) + ", in place of " + r.effect;
  }
  for (const Candidate& c : fitted.added) fitted_now[c.effect] = fit_source(c, measured, pixels);
  for (nlohmann::json& effect : effects) {
    const std::string name = effect["name"].get<std::string>();
    if (const auto found = fitted_now.find(name); found != fitted_now.end()) {
      effect["source"] = found->second;
      continue;
    }
    if (!before.is_array()) continue;
    for (const nlohmann::json& old : before) {
      if (old.is_object() && old.value("name", "") == name && old.contains("source")) effect["source"] = old["source"];
    }
  }
}

// --replace OLD=NEW, as pairs.
std::vector<std::pair<std::string, std::string>> replacements(const std::vector<std::string>& flags) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const std::string& flag : flags) {
    const size_t eq = flag.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == flag.size()) {
      throw InputError("--replace " + flag + ": expected EFFECT=REPLACEMENT, e.g. range_noise_linear=signal_precision");
    }
    out.emplace_back(flag.substr(0, eq), flag.substr(eq + 1));
  }
  return out;
}

// --add EFFECT, or an effect's JSON document: the parameters it names are fitted, from its values.
nlohmann::json effect_to_add(const std::string& flag) {
  if (flag.empty() || flag.front() != '{') return {{"name", flag}};
  nlohmann::json effect;
  try {
    effect = nlohmann::json::parse(flag);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(fmt::format("--add {}: not a JSON document ({})", flag, e.what()));
  }
  if (!effect.contains("name") || !effect["name"].is_string()) {
    throw InputError(fmt::format("--add {}: the document needs the effect's \"name\"", flag));
  }
  if (effect.size() == 1) return effect;
  for (const auto& [key, value] : effect.items()) {
    if (key != "name" && !value.is_number()) {
      throw InputError(
          fmt::format("--add {}: \"{}\" is not a number; the document gives the parameters to fit, "
                      "with the values they start from",
                      flag, key));
    }
  }
  (void)EffectChain::from_json(nlohmann::json::array({effect}), "--add " + flag);  // known keys, values in range
  return effect;
}

// --auto: what the diagnosis selects, replacements included, on the profile with its refits.
Fitted fit_automatically(const Measured& measured, const EffectChain& chain, const DiagnoseOptions& options) {
  MisfitOptions misfit_options;
  misfit_options.alpha = options.alpha;
  const Misfit misfit = find_misfit(measured.table, score_pixels(measured.table, 0, options.pool),
                                    measured.capture.frames.size(), misfit_options);
  const Diagnosis diagnosis = diagnose(measured.table, chain, misfit, options);
  Fitted out{diagnosis.fitted, {}, diagnosis.replace, diagnosis.selected};
  for (const ParameterMisfit& m : diagnosis.parameter_misfit) out.refits.push_back(m.refit);
  return out;
}

// --replace, --refit-noise and --add, in that order after the radiometry (fit_profile).
Fitted fit_as_asked(const FitFlags& flags, std::vector<nlohmann::json> add, const Measured& measured,
                    const EffectChain& chain, const DiagnoseOptions& options) {
  FitPlan plan;
  plan.replace = replacements(flags.replace);
  plan.refit_noise = flags.refit_noise;
  plan.add = std::move(add);
  FittedProfile fitted = fit_profile(measured.table, chain, plan, options);
  Fitted out{fitted.chain, {}, std::move(fitted.replaced), std::move(fitted.added)};
  for (const ParameterMisfit& m : fitted.refits) out.refits.push_back(m.refit);
  return out;
}

void print_fit(const Candidate& c, const std::string& replaces) {
  if (replaces.empty()) {
    std::printf("%s (%s): delta BIC %+.1f\n", c.effect.c_str(), c.catalogue.c_str(), c.delta_bic);
  } else {
    std::printf("%s (%s) in place of %s: delta BIC %+.1f\n", c.effect.c_str(), c.catalogue.c_str(), replaces.c_str(),
                c.delta_bic);
  }
  for (const FittedParameter& p : c.params) {
    std::printf("  %s = %.6g  (95 %%: %.6g .. %.6g", p.name.c_str(), p.value, p.ci95_lo, p.ci95_hi);
    if (!std::isnan(p.robust_lo)) std::printf("; robust %.6g .. %.6g", p.robust_lo, p.robust_hi);
    std::printf(")");
    if (const std::string bound = bound_note(p); !bound.empty()) {
      std::printf(" [%s: the data does not fix it]", bound.c_str());
    }
    std::printf("\n");
  }
}

int run_fit(const FitFlags& flags) {
  if (!flags.automatic && flags.add.empty() && flags.replace.empty() && !flags.refit_noise) {
    throw InputError("fit: give --add EFFECT, --replace EFFECT=REPLACEMENT or --refit-noise, or --auto");
  }
  std::vector<nlohmann::json> add;  // checked before the capture is read
  for (const std::string& flag : flags.add) add.push_back(effect_to_add(flag));
  // A unit's metadata gives its twin: the written profile keeps the unit's beam intrinsics.
  const SensorChoice sensor = load_sensor(flags.profile);
  const SensorProfile& profile = sensor.profile;
  const EffectChain chain = profile_chain(profile);
  Steps steps;
  const Measured measured = measure(flags.measured, profile, chain, steps);
  DiagnoseOptions options;
  options.alpha = flags.alpha;
  options.refit_range_noise = flags.refit_noise;
  options.datasheet_noise = datasheet_range_noise(profile.prod_line);
  WorkerPool pool(flags.measured.threads);
  options.pool = &pool;
  options.progress = [&steps](const std::string& what) { steps.note("fitting: " + what); };
  steps.start("fitting");
  const Fitted fitted = flags.automatic ? fit_automatically(measured, chain, options)
                                        : fit_as_asked(flags, std::move(add), measured, chain, options);
  steps.done();
  // The profile file as it is (a twin's as made from its unit), with the fitted chain and the notes.
  nlohmann::json document = sensor.document;
  document["effects"] = fitted.chain.to_json();
  attach_sources(document["effects"], sensor.document.value("effects", nlohmann::json()), fitted, measured,
                 measured.table.size());
  document["fit"] = fit_notes(fitted, measured, measured.table.size());
  if (fs::path(flags.out).has_parent_path()) fs::create_directories(fs::path(flags.out).parent_path());
  // Whole or not at all, and only once it reads back as a profile: --out may name the profile the
  // fit started from, which a failed write must not destroy.
  write_atomically(flags.out, [&](const fs::path& file) {
    std::ofstream out(file);
    out << document.dump(2) << "\n";
    out.close();
    if (!out) throw InputError("--out " + flags.out + ": write failed (disk full?)");
    load_profile(fs::absolute(file).string());  // a path, whatever its name ends with
  });
  if (fitted.added.empty() && fitted.replaced.empty() && flags.automatic) {
    std::printf("no effect added or replaced: none improves BIC significantly (--auto)\n");
  }
  for (const Candidate& c : fitted.refits) std::printf("refitted %s: delta BIC %+.1f\n", c.effect.c_str(), c.delta_bic);
  for (const Replacement& r : fitted.replaced) print_fit(r.with, r.effect);
  for (const Candidate& c : fitted.added) print_fit(c, "");
  std::printf("wrote %s\n", flags.out.c_str());
  return 0;
}

void setup_fit(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<FitFlags>();
  CLI::App* sub =
      app.add_subcommand("fit", "Add effects to a profile and fit them to a measured capture: writes a new profile");
  add_measured_options(sub, flags->measured);
  sub->add_option("--profile", flags->profile,
                  "the profile to extend (name or .json), or a unit's metadata .json (its twin)")
      ->required();
  auto* add =
      sub->add_option("--add", flags->add,
                      "effects to add and fit, in order: registry names, or an effect's JSON document, whose named "
                      "parameters are fitted from the values it gives "
                      "('{\"name\": \"incidence\", \"divergence_rad\": 0.002, \"saturation\": 0.3}')");
  auto* replace =
      sub->add_option("--replace", flags->replace,
                      "EFFECT=REPLACEMENT: the profile's range noise law replaced by another form, fitted in its place "
                      "(range_noise_linear=signal_precision, range_noise_linear=range_noise_piecewise, "
                      "range_noise_piecewise=range_noise_linear, range_noise_piecewise=signal_precision)");
  sub->add_flag("--refit-noise", flags->refit_noise,
                "refit the profile's range noise sigma(r) (its knots' sigmas), kept where significant; with --auto, "
                "as compare --diagnose --refit-noise");
  sub->add_flag("--auto", flags->automatic,
                "add (and replace) what the diagnosis selects, one at a time while BIC improves")
      ->excludes(add)
      ->excludes(replace);
  sub->add_option("--out", flags->out, "the new profile (.json)")->required();
  sub->add_option("--alpha", flags->alpha, "significance level of --auto's tests")
      ->check(CLI::Range(1e-12, 0.5))
      ->capture_default_str();
  sub->callback([&run, flags] { run = [flags] { return run_fit(*flags); }; });
}

const RegisterCommand registered_fit("fit", setup_fit);

}  // namespace
}  // namespace lidartwin::cli
