// Forward-stepwise search for the missing effect (lidar-physics.md 3.4, 3.5), in phases: the
// profile's radiometry and its own effects' parameters refitted; then round by round every
// candidate fitted (effect_fit.h) and, in the same rounds, the profile's range noise law replaced
// by laws of the other forms (noise_laws.h), the best kept by delta BIC; the kept ones refitted
// jointly; what still fails explained by the features it follows; what each candidate repairs.
#include "lidartwin/analysis/diagnosis.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>

#include <fmt/format.h>

#include "effect_fit.h"
#include "lidartwin/analysis/compare_report.h"
#include "lidartwin/analysis/pixel_likelihood.h"
#include "lidartwin/error.h"
#include "noise_laws.h"

namespace lidartwin {
namespace {

using analysis_detail::add_intervals;
using analysis_detail::candidate_specs;
using analysis_detail::CandidateSpec;
using analysis_detail::fit;
using analysis_detail::Intervals;
using analysis_detail::Placement;
using analysis_detail::refit_spec;
using analysis_detail::with_candidate;

// The search's state: the chain as the phases change it, and its NLL over the fitted rows.
struct Search {
  const PixelTable& table;
  const Misfit& misfit;
  const DiagnoseOptions& options;
  analysis_detail::FitRows rows;
  EffectChain chain;
  double nll = 0.0;
  int round = 0;  // of the search for missing effects
  double log_n() const { return std::log(static_cast<double>(rows.size())); }
  void say(const std::string& what) const {
    if (options.progress) options.progress(what);
  }
  // The whole table predicted by the chain `by`, valid until the next call: the steps that rescore every
  // pixel (a pattern, what is left unexplained, each candidate's repairs) share one copy of the
  // capture's table, as large as the capture, instead of copying it for each chain.
  const PixelTable& predicted_by(const EffectChain& by) const {
    if (scratch.size() != table.size()) scratch = table;
    repredict(table, by, scratch, rows.pool);
    return scratch;
  }
  mutable PixelTable scratch;
  // Its scores, likewise one set of arrays for every rescoring.
  const PixelScores& scored(const PixelTable& predicted) const {
    score_pixels(predicted, 0, rows.pool, scores);
    return scores;
  }
  mutable PixelScores scores;
  // The registry's candidates as the search began (a pool of pointers into them).
  std::vector<analysis_detail::CandidateSpec> candidates = analysis_detail::candidate_specs();
};

constexpr std::string_view kTails = "signal_outliers";  // E2's tails (tails_apply)

// What a round kept: an added candidate, or a law of another form in place of the noise law
// (`replaces`: its index), with its spec (for the joint refit and the shared-misfit tests).
struct Step {
  Candidate candidate;
  CandidateSpec spec;
  std::optional<size_t> replaces;
  size_t parameters_removed = 0;
  // A replacement after added effects: the chain with them refitted given it, and their values there.
  std::optional<EffectChain> joint;
  std::vector<Candidate> refitted;
};

// The last round: its additive candidates, what it kept, and the chain and NLL before that.
struct Kept {
  std::vector<Candidate> fits;
  Step step;
  EffectChain before;
  double before_nll = 0.0;
};

// The signal channel first: the capture's own radiometric constants (its gain and near-field
// overlap), against which every signal-driven candidate is judged. On its own channel, so it runs
// whether or not the range misfits.
void refit_radiometry_first(Search& s, Diagnosis& d) {
  if (!s.options.refit_profile) return;
  s.say("refitting the capture's radiometry");
  if (std::optional<ParameterMisfit> m = refit_radiometry(s.table, s.chain, s.options)) {
    s.chain = with_refit(s.chain, *m);
    d.parameter_misfit.push_back(std::move(*m));
  }
}

// Parameter misfit: the profile's own fittable effects refitted, each given the others as they
// stand, kept where the likelihood-ratio test and BIC say the profile's values misfit; the search
// for missing effects then starts from the refitted chain.
void refit_own_effects(Search& s, Diagnosis& d) {
  if (!s.options.refit_profile || s.misfit.failing.empty()) return;
  std::vector<std::pair<size_t, CandidateSpec>> own;
  for (size_t i = 0; i < s.chain.effects().size(); ++i) {
    if (std::optional<CandidateSpec> spec = refit_spec(*s.chain.effects()[i], s.options.refit_range_noise))
      own.emplace_back(i, std::move(*spec));
  }
  const double alpha = s.options.alpha / static_cast<double>(std::max<size_t>(own.size(), 1));
  for (const auto& [index, spec] : own) {
    s.say(fmt::format("refitting the profile's {}", spec.effect));
    std::optional<ParameterMisfit> m =
        analysis_detail::refit_in_place(s.table, s.rows, s.chain, s.nll, index, spec, s.options, alpha);
    if (m) d.parameter_misfit.push_back(std::move(*m));
  }
}

// The first round's candidates are ranked with their intervals (the report lists them all); later
// rounds' only compete, and the one kept gets its intervals then.
Intervals ranked_with(const Search& s) { return s.round == 1 ? Intervals::kWith : Intervals::kWithout; }

// Every candidate of the pool fitted given the chain, best first (with intervals: ranked_with).
std::vector<Candidate> fit_candidates(const Search& s, const std::vector<const CandidateSpec*>& pool) {
  std::vector<Candidate> fits;
  const Intervals intervals = ranked_with(s);
  for (const CandidateSpec* spec : pool) {
    s.say(fmt::format("round {}: fitting {}, {} of {}", s.round, spec->effect, fits.size() + 1, pool.size()));
    fits.push_back(fit(s.table, s.rows, Placement{s.chain, {}}, s.nll, *spec, nullptr, intervals));
  }
  std::sort(fits.begin(), fits.end(), [](const Candidate& a, const Candidate& b) { return a.delta_bic > b.delta_bic; });
  return fits;
}

// A replacement's delta BIC: not nested in the law it replaces, so BIC alone, counting its own free
// parameters less those of the replaced law that were fitted (the refitted sigmas of --refit-noise).
void score_replacement(Candidate& c, const Step& step, double log_n) {
  c.delta_bic = 2.0 * c.delta_nll -
                (static_cast<double>(step.spec.free.size()) - static_cast<double>(step.parameters_removed)) * log_n;
  c.p_value = 1.0;
}

// A law fitted in place of the noise law after effects were added (`kept`), which were fitted
// beside the old law: each refitted given the law, in turn, with the law itself (refit_in_turn). A
// law of the right form can lose to a wrong one while the added effects keep values that stood in
// for it: an incidence fitted beside a too-flat table takes up some of the weak oblique returns'
// spread that E2 gives, and given that incidence a linear sigma(r) scores above E2, jointly below.
void refit_with_kept(const Search& s, const std::vector<Step>& kept, Step& law) {
  const EffectChain with_law = Placement{s.chain, law.replaces, true}.chain_with(law.candidate.effect_json);
  const auto& effects = with_law.effects();
  const auto named = [&](const std::string& name) {
    return std::count_if(effects.begin(), effects.end(), [&](const auto& e) { return e->name() == name; });
  };
  std::vector<Candidate*> fitted;
  std::vector<CandidateSpec> specs;
  law.refitted.clear();
  law.refitted.reserve(kept.size());
  for (const Step& k : kept) {
    if (named(k.candidate.effect) != 1) return;  // refit_in_turn finds effects by name
    law.refitted.push_back(k.candidate);
    specs.push_back(k.spec);
  }
  if (named(law.candidate.effect) != 1) return;
  for (Candidate& c : law.refitted) fitted.push_back(&c);
  fitted.push_back(&law.candidate);
  specs.push_back(law.spec);
  EffectChain chain = with_law;
  double nll = s.nll - law.candidate.delta_nll;
  analysis_detail::refit_in_turn(s.table, s.rows, chain, nll, fitted, specs);
  law.candidate.delta_nll = s.nll - nll;
  score_replacement(law.candidate, law, s.log_n());
  law.joint = std::move(chain);
}

// The best law of another form in place of the chain's range noise, fitted there (with the effects
// `kept` so far refitted beside it); none if the chain has no noise law or no other form applies.
std::optional<Step> best_replacement(const Search& s, const Diagnosis& d, const std::vector<Step>& kept) {
  const std::optional<size_t> index = analysis_detail::range_noise_index(s.chain);
  if (!index) return std::nullopt;
  size_t removed = 0;  // the law's parameters the diagnosis fitted
  for (const ParameterMisfit& m : d.parameter_misfit) {
    if (m.index == *index && m.channel == "range") removed = m.refit.params.size();
  }
  std::optional<Step> best;
  for (CandidateSpec& form :
       analysis_detail::noise_law_forms(s.chain, *index, s.table, s.rows, s.options.datasheet_noise)) {
    Step step{{}, std::move(form), index, removed, {}, {}};
    s.say(fmt::format("round {}: fitting {} in place of the noise law", s.round, step.spec.effect));
    step.candidate =
        fit(s.table, s.rows, Placement{s.chain, index, true}, s.nll, step.spec, nullptr, Intervals::kWithout);
    score_replacement(step.candidate, step, s.log_n());
    // Only a law that already helps given the chain can win a round; refitting the added effects
    // beside one that does not would cost a diagnosis 2-3 fits a round for nothing.
    if (!kept.empty() && step.candidate.delta_bic >= s.options.min_delta_bic) {
      s.say(
          fmt::format("round {}: {} in place of the noise law: delta BIC {:+.0f}; refitting the added effects "
                      "beside it",
                      s.round, step.spec.effect, step.candidate.delta_bic));
      refit_with_kept(s, kept, step);
    }
    s.say(fmt::format("round {}: {} in place of the noise law: delta BIC {:+.0f}", s.round, step.spec.effect,
                      step.candidate.delta_bic));
    if (!best || step.candidate.delta_bic > best->candidate.delta_bic) best = std::move(step);
  }
  return best;
}

// The chain after a step.
EffectChain chain_after(const EffectChain& chain, const Step& step) {
  if (step.joint) return *step.joint;
  if (step.replaces) return Placement{chain, step.replaces, true}.chain_with(step.candidate.effect_json);
  return with_candidate(chain, step.candidate.effect_json);
}

// Candidates that helped last round and gain nothing given what it kept explain the same misfit:
// each is tested given the other (what was kept refitted with the candidate in the chain).
void note_shared(const Search& s, Diagnosis& d, const Kept& last, const std::vector<Candidate>& fits,
                 double corrected_alpha) {
  const Step& kept = last.step;
  const std::string kept_name = kept.replaces
                                    ? fmt::format("{} in place of {}", kept.candidate.effect, d.replace.back().effect)
                                    : kept.candidate.effect;
  for (const Candidate& alone : last.fits) {
    if (alone.effect == kept.candidate.effect || alone.delta_bic < s.options.min_delta_bic ||
        alone.p_value > corrected_alpha)
      continue;
    const auto now =
        std::find_if(fits.begin(), fits.end(), [&](const Candidate& c) { return c.effect == alone.effect; });
    if (now == fits.end() || now->delta_bic >= s.options.min_delta_bic) continue;
    const EffectChain with_alone = with_candidate(last.before, alone.effect_json);
    Candidate kept_given = fit(s.table, s.rows, Placement{with_alone, kept.replaces, kept.replaces.has_value()},
                               last.before_nll - alone.delta_nll, kept.spec, nullptr, Intervals::kWithout);
    if (kept.replaces) score_replacement(kept_given, kept, s.log_n());
    SharedMisfit shared{
        alone.effect, kept.candidate.effect, alone.delta_bic, now->delta_bic, kept_given.delta_bic, {}, ""};
    shared.sentence = fmt::format(
        "{} explains the same misfit as {}: delta BIC {:.0f} alone, {:.0f} given {}; {} keeps {:.0f} given {}, {}",
        alone.effect, kept_name, alone.delta_bic, now->delta_bic, kept.candidate.effect, kept.candidate.effect,
        kept_given.delta_bic, alone.effect,
        kept_given.delta_bic >= s.options.min_delta_bic
            ? fmt::format("so {} is kept", kept.candidate.effect)
            : fmt::format("so the data cannot tell them apart: {}, the larger, is kept", kept.candidate.effect));
    d.shared.push_back(std::move(shared));
  }
}

// Weighed against the strongest per-bin pattern of the misfit (unexplained.h), each given the
// other: a free value per bin of one feature (a bias per material, a detection rate per beam) is
// added to the chain and the candidate refitted given it, and the pattern refitted given the
// candidate. A candidate that gains nothing given the pattern while the pattern still gains given
// the candidate was only absorbing part of an effect it is not (a signal-driven dropout taking up
// some of a few weak beams' losses, a common drift one material's bias): it is passed over. Where
// each explains the other (a range walk and a bias per signal bin), the physical effect is kept.
std::optional<NotSelected> passed_over_for_pattern(const Search& s, const Candidate& best, const CandidateSpec& spec) {
  FeaturePattern pattern;
  PatternAdjustment adjust;
  {
    const PixelTable& now = s.predicted_by(s.chain);
    const PixelScores& now_scores = s.scored(now);
    pattern = strongest_pattern(now, now_scores);
    if (!pattern.quantity.empty()) adjust = pattern_adjustment(now, now_scores, pattern);
  }
  if (pattern.quantity.empty()) return std::nullopt;
  const double with_pattern = analysis_detail::total_nll(s.table, s.rows, s.chain, &adjust);
  const double pattern_bic = 2.0 * (s.nll - with_pattern) - pattern.dof * s.log_n();
  const Candidate given =
      fit(s.table, s.rows, Placement{s.chain, {}}, with_pattern, spec, &adjust, Intervals::kWithout);
  if (given.delta_bic >= s.options.min_delta_bic) return std::nullopt;
  const EffectChain with = with_candidate(s.chain, best.effect_json);
  const PixelTable& then = s.predicted_by(with);
  const PatternAdjustment after = pattern_adjustment(then, s.scored(then), pattern);
  const double pattern_given =  // the pattern's delta BIC given the candidate
      2.0 * (s.nll - best.delta_nll - analysis_detail::total_nll(s.table, s.rows, with, &after)) -
      pattern.dof * s.log_n();
  if (pattern_given < s.options.min_delta_bic) return std::nullopt;
  const std::string what = pattern.quantity == "detection"  ? "detection rate"
                           : pattern.quantity == "outliers" ? "outlier rate"
                                                            : pattern.quantity;
  return NotSelected{
      best.effect,
      best.delta_bic,
      pattern.quantity,
      pattern.feature,
      pattern_bic,
      given.delta_bic,
      pattern_given,
      fmt::format("{} (delta BIC {:.0f}) is not kept: given a free {} per {} bin (delta BIC {:.0f}) "
                  "it gains {:.0f}, while the bins still gain {:.0f} given it; no library effect has "
                  "the misfit's shape",
                  best.effect, best.delta_bic, what, pattern.feature, pattern_bic, given.delta_bic, pattern_given)};
}

// Whether E2's tails (signal_outliers) are among the candidates: where returns beyond 5 sigma fail
// in bins of signal, reflectivity or near-IR, against a reference made of the data (static, map:
// real captures, where they were found). Their likelihood has no SIMD path: against a scene they
// cost 2-6 times a whole diagnosis of the hall's captures with hidden E2, E3 or E12, whose weak
// returns fail beyond 5 sigma too, and there `fit --add signal_outliers` fits them.
bool tails_apply(const Search& s) {
  if (s.table.reference == PixelTable::Reference::kScene) return false;
  return std::any_of(s.misfit.failing.begin(), s.misfit.failing.end(), [](const FailingRegion& f) {
    return f.quantity == "outliers" && std::any_of(f.region.begin(), f.region.end(), [](const auto& feature) {
             return feature.first == "signal" || feature.first == "reflectivity" || feature.first == "near_ir";
           });
  });
}

// Whether a candidate can change the likelihood against the table's reference: a pixel's own
// temporal mean (static mode) hides what its card says it does.
bool visible_against_reference(std::string_view effect, PixelTable::Reference reference) {
  if (reference != PixelTable::Reference::kTemporalMean) return true;
  const std::optional<EffectCard> card = effect_card(effect);
  return card && card->seen_against_temporal_mean;
}

// Whether the chain has what the candidate needs before it (Effect::prerequisites: E2 reads the
// signal radiometry gives): a profile without radiometry is not offered the signal's effects.
bool placeable(const EffectChain& chain, const CandidateSpec& spec) {
  try {
    analysis_detail::with_candidate(chain, spec.start.is_null() ? nlohmann::json{{"name", spec.effect}} : spec.start);
    return true;
  } catch (const InputError&) {
    return false;
  }
}

// The rounds: every candidate of the pool fitted given the chain, and (until one is kept, where the
// profile misfits) the noise law's other forms in its place. The best is kept while it is very
// strong evidence (delta BIC > min_delta_bic) and, for an added candidate, significant; a
// replacement must also beat the round's best additive candidate. Returns the steps kept.
std::vector<Step> search_steps(Search& s, Diagnosis& d) {
  std::vector<const CandidateSpec*> pool;  // into s.candidates
  const bool tails = tails_apply(s);
  for (const CandidateSpec& spec : s.candidates) {
    const bool present = std::any_of(s.chain.effects().begin(), s.chain.effects().end(),
                                     [&](const auto& e) { return e->name() == spec.effect; });
    if (!present && (spec.effect != kTails || tails) && visible_against_reference(spec.effect, s.table.reference) &&
        placeable(s.chain, spec)) {
      pool.push_back(&spec);
    }
  }
  const double corrected_alpha = s.options.alpha / static_cast<double>(std::max<size_t>(pool.size(), 1));
  bool may_replace = s.options.refit_profile && !s.misfit.failing.empty();
  std::optional<Kept> last;
  std::vector<Step> steps;
  for (bool first = true; static_cast<int>(d.selected.size()) < s.options.max_effects && (!pool.empty() || may_replace);
       first = false) {
    ++s.round;
    const std::vector<Candidate> fits = fit_candidates(s, pool);
    if (first) d.ranked = fits;
    if (last) note_shared(s, d, *last, fits, corrected_alpha);
    const Candidate* best = fits.empty() ? nullptr : &fits.front();
    std::optional<Step> form = may_replace ? best_replacement(s, d, steps) : std::nullopt;
    Step step;
    if (form && form->candidate.delta_bic >= s.options.min_delta_bic &&
        (!best || form->candidate.delta_bic > best->delta_bic)) {
      step = std::move(*form);
      add_intervals(s.table, s.rows, Placement{step.joint ? *step.joint : s.chain, step.replaces, true}, step.spec,
                    step.candidate);
      // The added effects as the law's fit left them (refit_with_kept).
      for (const Candidate& refitted : step.refitted) {
        for (Candidate& c : d.selected) {
          if (c.effect == refitted.effect) c.params = refitted.params, c.effect_json = refitted.effect_json;
        }
        for (Step& earlier : steps) {
          if (earlier.candidate.effect == refitted.effect) earlier.candidate = refitted;
        }
      }
      Replacement r{std::string(s.chain.effects()[*step.replaces]->name()),
                    "",
                    *step.replaces,
                    step.candidate,
                    step.parameters_removed,
                    best ? best->effect : "",
                    best ? best->delta_bic : 0.0,
                    ""};
      r.catalogue = effect_catalogue(r.effect).value_or("");
      d.replace.push_back(std::move(r));
      may_replace = false;
    } else {
      if (!best || best->delta_bic < s.options.min_delta_bic || best->p_value > corrected_alpha) break;
      step.candidate = *best;
      step.spec =
          **std::find_if(pool.begin(), pool.end(), [&](const CandidateSpec* c) { return c->effect == best->effect; });
      if (std::optional<NotSelected> n = passed_over_for_pattern(s, *best, step.spec)) {
        d.not_selected.push_back(std::move(*n));
        break;
      }
      if (ranked_with(s) == Intervals::kWithout) {
        add_intervals(s.table, s.rows, Placement{s.chain, {}}, step.spec, step.candidate);
      }
      d.selected.push_back(step.candidate);
    }
    last = Kept{fits, step, s.chain, s.nll};
    s.chain = chain_after(s.chain, step);
    s.nll -= step.candidate.delta_nll;
    std::erase_if(pool, [&](const CandidateSpec* c) {
      return std::any_of(s.chain.effects().begin(), s.chain.effects().end(),
                         [&](const auto& e) { return e->name() == c->effect; });
    });
    steps.push_back(std::move(step));
  }
  return steps;
}

// The kept steps refitted jointly (effect_fit.h: each given all the others), their values written
// back to the diagnosis' lists.
void refit_steps_jointly(Search& s, Diagnosis& d, const std::vector<Step>& steps) {
  std::vector<Candidate*> fitted;
  std::vector<CandidateSpec> specs;
  size_t selected = 0;
  for (const Step& step : steps) {
    fitted.push_back(step.replaces ? &d.replace.front().with : &d.selected[selected++]);
    specs.push_back(step.spec);
  }
  analysis_detail::refit_jointly(s.table, s.rows, s.chain, s.nll, fitted, specs);
}

// What the profile with the refits, the replacement and the selected effects still gets wrong, and
// what it follows.
void explain_remaining(const Search& s, Diagnosis& d) {
  MisfitOptions misfit_options;
  misfit_options.alpha = s.options.alpha;
  const PixelTable& final_table = s.predicted_by(s.chain);
  const PixelScores& final_scores = s.scored(final_table);
  const Misfit remaining = find_misfit(final_table, final_scores, s.misfit.summary.frames, misfit_options);
  d.unexplained = explain_misfit(final_table, final_scores, remaining, s.options.alpha);
  d.remaining_failing = remaining.failing.size();
  const MisfitSummary& r = remaining.summary;
  d.remaining_excess_se = r.nll_se > 0 ? (r.nll_per_pixel - r.nll_expected) / r.nll_se : 0.0;
  const bool fitted = !d.selected.empty() || !d.replace.empty() || !d.parameter_misfit.empty();
  if (fitted) {
    d.remaining_note = excess_note(waterfall_step("the profile", s.table, s.misfit),
                                   waterfall_step("the fitted model", final_table, remaining));
  }
  if (fitted && d.remaining_failing > 0) {
    // The case: a divergence fitted beside a wrong noise law came out 0.00192 [0.00191,
    // 0.00193] against a true 0.00227. Curvature intervals are conditional on the rest of the model.
    d.intervals_caveat = fmt::format(
        "The intervals hold if the rest of the model is right, and it is not: with the fitted effects the model "
        "still fails in {} regions (NLL {:+.1f} standard errors). A fitted value can then lie outside its interval, "
        "as the misfit left over pulls it; the robust interval allows for a wrong spread and for neighbouring pixels "
        "that share their noise, not for a missing effect. Explain what is left, then fit again.",
        d.remaining_failing, d.remaining_excess_se);
  }
}

// The failing regions of the profile's chain that no longer fail with `chain` (the whole table
// rescored).
std::vector<std::string> repairs(const Search& s, const EffectChain& chain) {
  const PixelTable& with = s.predicted_by(chain);
  MisfitOptions misfit_options;
  misfit_options.alpha = s.options.alpha;
  const Misfit after = find_misfit(with, s.scored(with), s.misfit.summary.frames, misfit_options);
  std::set<std::pair<std::string, std::string>> still;
  for (const FailingRegion& f : after.failing) still.insert({f.quantity, describe(f.region)});
  std::vector<std::string> out;
  for (const FailingRegion& f : s.misfit.failing) {
    if (!still.count({f.quantity, describe(f.region)})) out.push_back(f.sentence);
  }
  return out;
}

// What each first-round candidate that helps, and each replacement, repairs; and the regions both
// candidates of a shared misfit repair.
void note_repairs(const Search& s, Diagnosis& d) {
  for (Candidate& c : d.ranked) {
    if (c.delta_bic > 0.0) c.repairs = repairs(s, with_candidate(d.refitted, c.effect_json));
  }
  for (Replacement& r : d.replace) {
    r.with.repairs = repairs(s, Placement{d.refitted, r.index, true}.chain_with(r.with.effect_json));
  }
  const auto repairs_of = [&](const std::string& effect) {
    const auto c =
        std::find_if(d.ranked.begin(), d.ranked.end(), [&](const Candidate& r) { return r.effect == effect; });
    return c == d.ranked.end() ? std::set<std::string>{} : std::set<std::string>(c->repairs.begin(), c->repairs.end());
  };
  for (SharedMisfit& shared : d.shared) {
    const std::set<std::string> with = repairs_of(shared.with);
    for (const std::string& r : repairs_of(shared.effect)) {
      if (with.count(r)) shared.repairs.push_back(r);
    }
  }
}

// "range_noise_linear (E1) has the wrong form: signal_precision (E2) in its place, k_m 0.3 (95 %:
// 0.29-0.31), ...; delta BIC +N (2 parameters for 0), +M over the round's best additive candidate (X, +K)".
std::string replacement_sentence(const Replacement& r) {
  std::string params;
  for (const FittedParameter& p : r.with.params) {
    params += fmt::format(", {} {:.4g} (95 %: {:.4g}–{:.4g})", p.name, p.value, p.ci95_lo, p.ci95_hi);
  }
  const std::string against =
      r.additive.empty() ? std::string("no additive candidate to compare")
                         : fmt::format("{:+.0f} over the round's best additive candidate ({}, {:+.0f})",
                                       r.with.delta_bic - r.additive_delta_bic, r.additive, r.additive_delta_bic);
  return fmt::format("{} ({}) has the wrong form: {} ({}) in its place{}; delta BIC {:+.0f} ({} parameters for {}), {}",
                     r.effect, r.catalogue, r.with.effect, r.with.catalogue, params, r.with.delta_bic,
                     r.with.params.size(), r.parameters_removed, against);
}

}  // namespace

Diagnosis diagnose(const PixelTable& table, const EffectChain& chain, const Misfit& misfit,
                   const DiagnoseOptions& options) {
  Diagnosis d;
  Search s{table, misfit, options, analysis_detail::subsample(table, options.max_pixels, options.pool), chain, 0.0,
           0,     {},     {}};
  d.pixels = s.rows.size();
  refit_radiometry_first(s, d);
  s.nll = analysis_detail::total_nll(table, s.rows, s.chain);
  refit_own_effects(s, d);
  d.refitted = s.chain;
  const std::vector<Step> steps = search_steps(s, d);
  if (!steps.empty()) s.say("refitting the kept effects jointly");
  refit_steps_jointly(s, d, steps);
  for (Replacement& r : d.replace) r.sentence = replacement_sentence(r);
  d.fitted = s.chain;
  s.say("what the fitted chain leaves unexplained");
  explain_remaining(s, d);
  // A misfit no library effect explains is a missing effect too.
  d.verdict = !d.selected.empty() || !d.unexplained.empty() ? "missing effect"
              : !d.replace.empty()                          ? "wrong effect form"
                                                            : "no missing effect";
  s.say("what each candidate repairs");
  note_repairs(s, d);
  return d;
}

}  // namespace lidartwin
