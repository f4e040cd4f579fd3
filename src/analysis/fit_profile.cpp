// `fit`'s fits (diagnosis.h: fit_effects, fit_profile): the effects a user names, added to or put
// in place of the profile's own, fitted with the diagnosis' machinery (effect_fit.h), in phases.
#include <algorithm>
#include <cmath>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "effect_fit.h"
#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/error.h"
#include "noise_laws.h"

namespace lidartwin {
namespace {

using analysis_detail::candidate_specs;
using analysis_detail::CandidateSpec;
using analysis_detail::fit;
using analysis_detail::Placement;

// The effect as a document to fit: one the search lists, or one a user registered without a
// catalogue id; anything else (unknown, or a library effect whose parameters are not a handful of
// numbers) is refused.
nlohmann::json fittable_document(const std::string& name) {
  const std::optional<std::string> catalogue = effect_catalogue(name);
  if (!analysis_detail::candidate_spec(name) && (!catalogue || !catalogue->empty())) {
    throw InputError(
        fmt::format("--add {}: not an effect the fit can estimate; fittable: {}, and effects "
                    "registered without a catalogue id",
                    name, fmt::join(fittable_effects(), ", ")));
  }
  return {{"name", name}};
}

// What a fit changes, as it goes: the chain, its NLL over the fitted rows, and the fitted effects
// with their specs (for the joint refit).
struct Fitting {
  const PixelTable& table;
  analysis_detail::FitRows rows;
  EffectChain chain;
  double nll = 0.0;
  std::vector<Candidate*> fitted;
  std::vector<CandidateSpec> specs;
};

// `effect` replaced by the form named `by` (noise_laws.h), fitted in its place.
Replacement replace_effect(Fitting& f, const std::string& effect, const std::string& by,
                           const DiagnoseOptions& options) {
  const std::string what = fmt::format("--replace {}={}", effect, by);
  if (!analysis_detail::is_range_noise_law(effect)) {
    throw InputError(what + ": only the profile's range noise law (range_noise_linear, range_noise_piecewise) " +
                     "can be replaced");
  }
  const auto& effects = f.chain.effects();
  const auto at = std::find_if(effects.begin(), effects.end(), [&](const auto& e) { return e->name() == effect; });
  if (at == effects.end()) throw InputError(what + ": the profile's chain has no " + effect);
  const size_t index = static_cast<size_t>(at - effects.begin());
  std::vector<CandidateSpec> forms =
      analysis_detail::noise_law_forms(f.chain, index, f.table, f.rows, options.datasheet_noise);
  const auto form = std::find_if(forms.begin(), forms.end(), [&](const CandidateSpec& s) { return s.effect == by; });
  if (form == forms.end()) {
    std::vector<std::string> names;
    for (const CandidateSpec& s : forms) names.push_back(s.effect);
    throw InputError(fmt::format("{}: {} cannot stand in its place here; it can be replaced by: {}{}", what, by,
                                 names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", ")),
                                 by == "range_noise_piecewise" ? " (a table needs the product line's datasheet table "
                                                                 "in a shipped profile)"
                                                               : ""));
  }
  Replacement r{effect, effect_catalogue(effect).value_or(""), index, {}, 0, "", 0.0, ""};
  r.with = fit(f.table, f.rows, Placement{f.chain, index, true}, f.nll, *form);
  r.with.delta_bic =
      2.0 * r.with.delta_nll - static_cast<double>(form->free.size()) * std::log(static_cast<double>(f.rows.size()));
  r.with.p_value = 1.0;  // not nested: BIC alone
  f.chain = Placement{f.chain, index, true}.chain_with(r.with.effect_json);
  f.nll -= r.with.delta_nll;
  f.specs.push_back(*form);
  return r;
}

// The chain's range noise law refitted in place (its sigmas), kept where significant.
std::optional<ParameterMisfit> refit_noise(Fitting& f, const DiagnoseOptions& options) {
  const std::optional<size_t> index = analysis_detail::range_noise_index(f.chain);
  if (!index) return std::nullopt;
  const std::optional<CandidateSpec> spec = analysis_detail::refit_spec(*f.chain.effects()[*index], true);
  if (!spec || spec->free.empty()) return std::nullopt;
  return analysis_detail::refit_in_place(f.table, f.rows, f.chain, f.nll, *index, *spec, options, options.alpha);
}

// `effect` added before the chain's range limits and fitted.
Candidate add_effect(Fitting& f, const nlohmann::json& effect) {
  const std::string name = effect.value("name", "");
  for (const auto& e : f.chain.effects()) {
    if (e->name() == name) throw InputError(fmt::format("--add {}: the profile's chain already has it", name));
  }
  const std::optional<CandidateSpec> listed = analysis_detail::candidate_spec(name);
  f.specs.push_back(listed && effect.size() == 1 ? *listed : analysis_detail::spec_of(effect));
  Candidate c = fit(f.table, f.rows, Placement{f.chain, {}}, f.nll, f.specs.back());
  f.chain = analysis_detail::with_candidate(f.chain, c.effect_json);
  f.nll -= c.delta_nll;
  return c;
}

}  // namespace

std::vector<std::string> fittable_effects() {
  std::vector<std::string> names;
  for (const CandidateSpec& spec : candidate_specs()) names.emplace_back(spec.effect);
  return names;
}

std::vector<Candidate> fit_effects(const PixelTable& table, const EffectChain& chain,
                                   const std::vector<std::string>& effects, const DiagnoseOptions& options) {
  std::vector<nlohmann::json> documents;
  for (const std::string& name : effects) documents.push_back(fittable_document(name));
  return fit_effects(table, chain, documents, options);
}

std::vector<Candidate> fit_effects(const PixelTable& table, const EffectChain& chain,
                                   const std::vector<nlohmann::json>& effects, const DiagnoseOptions& options) {
  Fitting f{table, analysis_detail::subsample(table, options.max_pixels, options.pool), chain, 0.0, {}, {}};
  f.nll = analysis_detail::total_nll(table, f.rows, f.chain);
  std::vector<Candidate> added;
  for (const nlohmann::json& effect : effects) added.push_back(add_effect(f, effect));
  for (Candidate& c : added) f.fitted.push_back(&c);
  analysis_detail::refit_jointly(table, f.rows, f.chain, f.nll, f.fitted, f.specs);
  return added;
}

FittedProfile fit_profile(const PixelTable& table, const EffectChain& chain, const FitPlan& plan,
                          const DiagnoseOptions& options) {
  FittedProfile out{chain, {}, {}, {}};
  Fitting f{table, analysis_detail::subsample(table, options.max_pixels, options.pool), chain, 0.0, {}, {}};
  // The capture's own radiometric constants first, as the diagnosis does: every signal-driven
  // effect is fitted against the expected signal they make.
  if (std::optional<ParameterMisfit> m = refit_radiometry(table, f.chain, options)) {
    f.chain = with_refit(f.chain, *m);
    out.refits.push_back(std::move(*m));
  }
  f.nll = analysis_detail::total_nll(table, f.rows, f.chain);
  for (const auto& [effect, by] : plan.replace) out.replaced.push_back(replace_effect(f, effect, by, options));
  if (plan.refit_noise) {
    if (std::optional<ParameterMisfit> m = refit_noise(f, options)) out.refits.push_back(std::move(*m));
  }
  for (const nlohmann::json& effect : plan.add) {
    out.added.push_back(add_effect(f, effect.size() == 1 ? fittable_document(effect.value("name", "")) : effect));
  }
  // Jointly: each replacement and added effect given all the others (in the order of f.specs).
  for (Replacement& r : out.replaced) f.fitted.push_back(&r.with);
  for (Candidate& c : out.added) f.fitted.push_back(&c);
  analysis_detail::refit_jointly(table, f.rows, f.chain, f.nll, f.fitted, f.specs);
  out.chain = f.chain;
  return out;
}

EffectChain with_refit(const EffectChain& chain, const ParameterMisfit& refit) {
  return Placement{chain, refit.index}.chain_with(refit.refit.effect_json);
}

EffectChain chain_with(const EffectChain& chain, const std::vector<Candidate>& added) {
  EffectChain out = chain;
  for (const Candidate& c : added) out = analysis_detail::with_candidate(out, c.effect_json);
  return out;
}

}  // namespace lidartwin
