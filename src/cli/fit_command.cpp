// `lidartwin fit`: a new profile with effects added to the measured capture's profile and their
// parameters fitted by maximum likelihood on it (the diagnosis' fits), written as a profile file
// that record, serve and compare read as they are. The fitted values and their 95 % intervals go
// into the profile's "fit" section, next to the effects.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "cli/command.h"
#include "cli/measured_inputs.h"
#include "cli/unit_twin.h"
#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/misfit.h"
#include "lidartwin/error.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin::cli {
namespace {

namespace fs = std::filesystem;

struct FitFlags {
  MeasuredFlags measured;
  std::string profile;
  std::vector<std::string> add;
  bool automatic = false;
  std::string out;
  double alpha = 0.01;
};

nlohmann::json fit_notes(const std::vector<Candidate>& fits, const Measured& measured, size_t pixels) {
  nlohmann::json effects = nlohmann::json::array();
  for (const Candidate& c : fits) {
    nlohmann::json params = nlohmann::json::object();
    for (const FittedParameter& p : c.params) params[p.name] = {{"value", p.value}, {"ci95", {p.ci95_lo, p.ci95_hi}}};
    effects.push_back({{"effect", c.effect},
                       {"catalogue", c.catalogue},
                       {"delta_bic", c.delta_bic},
                       {"p_value", c.p_value},
                       {"params", params}});
  }
  return {{"comment", "written by lidartwin fit: effects added and fitted by maximum likelihood"},
          {"capture", measured.inputs["capture"]},
          {"frames", measured.inputs["frames"]},
          {"pixels", pixels},
          {"effects", effects}};
}

int run_fit(const FitFlags& flags) {
  if (flags.add.empty() == !flags.automatic) throw InputError("fit: give --add EFFECT (one or more) or --auto");
  // A unit's metadata gives its twin: the written profile keeps the unit's beam intrinsics.
  const SensorChoice sensor = load_sensor(flags.profile);
  const SensorProfile& profile = sensor.profile;
  const EffectChain chain = EffectChain::from_json(profile.effects, "profile " + profile.name + ": /effects");
  Steps steps;
  const Measured measured = measure(flags.measured, profile, chain, steps);
  DiagnoseOptions options;
  options.alpha = flags.alpha;
  std::vector<Candidate> fits, noted;
  EffectChain base = chain;
  steps.start("fitting");
  if (flags.automatic) {
    MisfitOptions misfit_options;
    misfit_options.alpha = flags.alpha;
    const Misfit misfit =
        find_misfit(measured.table, score_pixels(measured.table), measured.capture.frames.size(), misfit_options);
    const Diagnosis diagnosis = diagnose(measured.table, chain, misfit, options);
    fits = diagnosis.selected;
    base = diagnosis.refitted;  // the profile's own effects whose parameters misfit, refitted
    for (const ParameterMisfit& m : diagnosis.parameter_misfit) noted.push_back(m.refit);
  } else {
    // The capture's own radiometric constants first, as the diagnosis does: the added effects are
    // fitted against the expected signal they make.
    if (std::optional<ParameterMisfit> m = refit_radiometry(measured.table, chain, options)) {
      base = with_refit(chain, *m);
      noted.push_back(m->refit);
    }
    fits = fit_effects(measured.table, base, flags.add, options);
  }
  steps.done();
  noted.insert(noted.end(), fits.begin(), fits.end());
  // The profile file as it is (a twin's as made from its unit), with the fitted chain and the notes.
  nlohmann::json document = sensor.document;
  document["effects"] = chain_with(base, fits).to_json();
  document["fit"] = fit_notes(noted, measured, measured.table.size());
  if (fs::path(flags.out).has_parent_path()) fs::create_directories(fs::path(flags.out).parent_path());
  std::ofstream out(flags.out);
  out << document.dump(2) << "\n";
  if (!out) throw InputError("--out " + flags.out + ": write failed");
  out.close();
  load_profile(flags.out);  // what was written reads back as a profile
  if (fits.empty()) std::printf("no effect added: none improves BIC significantly (--auto)\n");
  for (const Candidate& c : fits) {
    std::printf("%s (%s): delta BIC %+.1f\n", c.effect.c_str(), c.catalogue.c_str(), c.delta_bic);
    for (const FittedParameter& p : c.params) {
      std::printf("  %s = %.6g  (95 %%: %.6g .. %.6g)\n", p.name.c_str(), p.value, p.ci95_lo, p.ci95_hi);
    }
  }
  std::printf("wrote %s\n", flags.out.c_str());
  return 0;
}

void setup_fit(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<FitFlags>();
  CLI::App* sub =
      app.add_subcommand("fit", "Add effects to a profile and fit them to a measured capture: writes a new profile");
  add_measured_options(sub, flags->measured, /*with_static=*/false);
  sub->add_option("--profile", flags->profile,
                  "the profile to extend (name or .json), or a unit's metadata .json (its twin)")
      ->required();
  auto* add = sub->add_option("--add", flags->add, "effects to add and fit, in order (registry names)");
  sub->add_flag("--auto", flags->automatic, "add what the diagnosis selects, one at a time while BIC improves")
      ->excludes(add);
  sub->add_option("--out", flags->out, "the new profile (.json)")->required();
  sub->add_option("--alpha", flags->alpha, "significance level of --auto's tests")
      ->check(CLI::Range(1e-12, 0.5))
      ->capture_default_str();
  sub->callback([&run, flags] { run = [flags] { return run_fit(*flags); }; });
}

const RegisterCommand registered("fit", setup_fit);

}  // namespace
}  // namespace lidartwin::cli
