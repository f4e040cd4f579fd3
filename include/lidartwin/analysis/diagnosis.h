#pragma once
// Which physical effect is missing (lidar-physics.md 3.4): every library effect the profile lacks
// is added to its chain in turn, its parameters fitted by maximum likelihood (NLopt) on the pixel
// table, and the candidates ranked by the improvement in BIC, with a likelihood-ratio test and the
// failing regions each one repairs. Forward stepwise: the best is kept and the others refitted
// given it while the improvement stays significant, so two hidden effects are both found. The
// profile's range noise law may instead have the wrong form: laws of the other forms are tried in
// its place in the same rounds, and compared with the added effects by BIC.
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/pixel_table.h"
#include "lidartwin/analysis/unexplained.h"
#include "lidartwin/effects/effect_chain.h"

namespace lidartwin {

class WorkerPool;  // lidartwin/frame/worker_pool.h

// A fitted value with two 95 % intervals. ci95: from the observed information (the NLL's curvature),
// right when the model is right and pixels are independent. robust: the sandwich H^-1 J H^-1, J the
// score's covariance the data show over blocks of neighbouring pixels; it widens where the model's
// spread is wrong or neighbouring pixels share their noise. Neither allows for the rest of the model
// being wrong: a value fitted beside a wrong noise law can lie outside both (Diagnosis::
// intervals_caveat). NaN where not computed (E10's closed form).
struct FittedParameter {
  std::string name;
  double value = 0.0;
  double ci95_lo = 0.0, ci95_hi = 0.0;
  double robust_lo = std::numeric_limits<double>::quiet_NaN(), robust_hi = std::numeric_limits<double>::quiet_NaN();
  // The search's bounds (NaN: not known): a value at one, or an interval that spans both, says the
  // data does not fix the parameter within them.
  double lower = std::numeric_limits<double>::quiet_NaN(), upper = std::numeric_limits<double>::quiet_NaN();
};

// "at its upper bound 2", "its interval spans its bounds -2 .. 2", or "" where the fit fixed it
// inside them: the terminal, report.json ("bound") and report.html say it beside the value.
std::string bound_note(const FittedParameter& p);

struct Candidate {
  std::string effect;     // registry name
  std::string catalogue;  // lidar-physics.md id, e.g. "E4"
  std::vector<FittedParameter> params;
  double delta_nll = 0.0;            // NLL of the chain without it minus with it, nats over the fitted pixels
  double delta_bic = 0.0;            // 2 delta_nll - k ln n: > 0 favours the effect
  double p_value = 1.0;              // likelihood-ratio test, chi-square with k degrees of freedom
  std::vector<std::string> repairs;  // sentences of the failing regions that no longer fail with it
  nlohmann::json effect_json;        // the fitted effect, as a profile lists it
};

// An effect the profile has whose parameters misfit: refitted in place (the same free parameters
// a candidate fits), with the profile's values it replaced.
struct ParameterMisfit {
  Candidate refit;  // effect_json: the whole effect with the refitted values
  std::vector<std::pair<std::string, double>> old_values;
  size_t index = 0;  // its place in the profile's chain
  // What the refit was judged on: "range" (the pixel likelihood, as the candidates are) or "signal"
  // (the radiometry, by least squares in ln SIGNAL: refit_radiometry).
  std::string channel = "range";
};

// The round's best candidate, passed over because it gains nothing once the misfit's strongest
// per-bin pattern along one feature is allowed for (strongest_pattern, pattern_adjustment) while
// the pattern still gains given it: the misfit is left to `unexplained`.
struct NotSelected {
  std::string effect;
  double delta_bic = 0.0;
  std::string quantity, feature;  // the pattern
  double pattern_delta_bic = 0.0;
  double delta_bic_given_pattern = 0.0;
  double pattern_delta_bic_given_effect = 0.0;
  std::string sentence;
};

// Two candidates that explain the same misfit (say so, and test each given the other):
// `effect` helped alone but gains nothing once `with` (the round's kept effect) is in the chain;
// `with` is refitted given `effect` to tell whether it explains more (then it is rightly kept) or
// the data cannot tell them apart (each is nothing given the other: the larger is kept).
struct SharedMisfit {
  std::string effect, with;
  double delta_bic_alone = 0.0;       // effect's, in the round before `with` was kept
  double delta_bic_given = 0.0;       // effect's given `with`
  double with_delta_bic_given = 0.0;  // `with`'s given effect
  std::vector<std::string> repairs;   // failing regions both repair (first-round candidates)
  std::string sentence;
};

// One of the profile's own effects whose form is wrong: its range noise law (E1) replaced
// by a law of another form (the datasheet table, the linear law, or E2's signal-driven sigma alone),
// fitted in its place. Not nested in the profile's law, so judged by BIC alone (lidar-physics.md
// 3.3): `with.delta_bic` counts the replacement's free parameters less those of `effect` that were
// fitted (parameters_removed: the law's sigmas, where --refit-noise refitted them), and it is kept
// when it exceeds min_delta_bic and the round's best additive candidate's.
struct Replacement {
  std::string effect;     // the profile's effect replaced (registry name)
  std::string catalogue;  // its lidar-physics.md id
  size_t index = 0;       // its place in the chain, which the replacement takes
  Candidate with;         // p_value unused (not nested)
  size_t parameters_removed = 0;
  std::string additive;  // the round's best additive candidate ("" if none), and its delta BIC
  double additive_delta_bic = 0.0;
  std::string sentence;
};

struct Diagnosis {
  // "no missing effect", "missing effect" (selected or unexplained), or "wrong effect form" (a
  // replacement and nothing missing)
  std::string verdict;
  std::vector<ParameterMisfit> parameter_misfit;  // the profile's own effects refitted, in chain order
  std::vector<Replacement> replace;               // the profile's own effects replaced (at most its noise law)
  std::vector<Candidate> ranked;                  // first round, best first
  std::vector<Candidate> selected;                // kept, in the order added
  std::vector<NotSelected> not_selected;
  std::vector<SharedMisfit> shared;
  // What still fails with the selected effects added, and the features it follows.
  std::vector<UnexplainedMisfit> unexplained;
  // What the fitted chain still fails: regions at alpha, and the NLL's excess in standard errors.
  size_t remaining_failing = 0;
  double remaining_excess_se = 0.0;
  // Where the fitted chain's NLL is lower but its excess further from 0 than the profile's (or the
  // reverse): why (excess_note).
  std::string remaining_note;
  // Said when something was fitted and misfit remains: the intervals hold given the rest of the
  // model, which is then wrong somewhere, and a fitted value can lie outside them (FittedParameter).
  std::string intervals_caveat;
  size_t pixels = 0;     // pixels the fits used
  EffectChain refitted;  // the profile's chain with the refits (neither replaced nor selected applied)
  EffectChain fitted;    // with the replacements and the selected effects too, jointly refitted
};

struct DiagnoseOptions {
  double alpha = 0.01;          // the LRT's level, Bonferroni-corrected over the candidates
  double min_delta_bic = 10.0;  // "very strong" evidence on the Kass-Raftery scale
  // The fits' pixels: every k-th that meets a surface, k = (their number / max_pixels) rounded down,
  // so between max_pixels and twice that (an odd stride would fit every beam: effect_fit.cpp).
  size_t max_pixels = 200'000;
  int max_effects = 3;
  // Refit the profile's own fittable effects first, where the profile fails somewhere (a profile
  // that fits everywhere keeps its values): compare --keep-profile turns it off.
  bool refit_profile = true;
  // With refit_profile: the range noise's sigmas too (compare --refit-noise). Off by default, as
  // sigma(r) can take up part of a missing spread effect along range.
  bool refit_range_noise = false;
  // The product line's datasheet table (a range_noise_piecewise effect: datasheet_range_noise),
  // the form tried in place of a linear law; none: that form is not tried. With refit_profile,
  // the other forms (E2 alone, the linear law in place of a table) are always tried.
  std::optional<nlohmann::json> datasheet_noise;
  // The workers the fits' likelihood sums are spread over (the same results whatever its size);
  // none: the calling thread.
  WorkerPool* pool = nullptr;
  // Told what the search does as it goes ("round 1: fitting incidence, 3 of 8"): a long search is
  // not silent. None: quiet.
  std::function<void(const std::string&)> progress;
};

// chain: the profile's. misfit: find_misfit's result on the same table (for the repairs).
Diagnosis diagnose(const PixelTable& table, const EffectChain& chain, const Misfit& misfit,
                   const DiagnoseOptions& options = {});

nlohmann::json diagnosis_json(const Diagnosis& diagnosis);

// The profile's radiometry refitted to the measured channels (lidar-physics.md 2.2): its gain K and
// near-field overlap g(r) (r0, p) to SIGNAL by Poisson quasi-likelihood, its ambient level to
// NEAR_IR by least squares. A capture from another unit or generator has its own; every
// signal-driven effect is judged against the expected signal, so the diagnosis and `fit` refit
// these first. None when the profile has no radiometry, the capture neither channel, or no part is
// significant (options' alpha and min_delta_bic) and moves its channel by 2 % RMS or more.
std::optional<ParameterMisfit> refit_radiometry(const PixelTable& table, const EffectChain& chain,
                                                const DiagnoseOptions& options = {});

// The chain with a refitted effect in its place.
EffectChain with_refit(const EffectChain& chain, const ParameterMisfit& refit);

// The effects the diagnosis can fit (registry names).
std::vector<std::string> fittable_effects();
// Fits `effects` one after the other, each given the chain with those before it; throws InputError
// naming an effect that is not fittable or already in the chain. Fittable: the effects the search
// lists (fittable_effects()), and effects a user registered (register_effect without a catalogue
// id), whose parameters that are not fixed are all fitted.
std::vector<Candidate> fit_effects(const PixelTable& table, const EffectChain& chain,
                                   const std::vector<std::string>& effects, const DiagnoseOptions& options = {});
// The same with each effect as a profile lists it: its fixed parameters (which material, which
// beams) and the free ones' starting values.
std::vector<Candidate> fit_effects(const PixelTable& table, const EffectChain& chain,
                                   const std::vector<nlohmann::json>& effects, const DiagnoseOptions& options = {});
// The chain with the fitted effects inserted (before its range limits), in order.
EffectChain chain_with(const EffectChain& chain, const std::vector<Candidate>& added);

// What `fit` changes in a profile, in this order after refitting its radiometry: its own effects
// replaced by another form ({effect, replacement}: `fit --replace range_noise_linear=signal_precision`;
// the forms the diagnosis tries), its range noise's sigmas refitted (--refit-noise; kept where
// significant, as the diagnosis' parameter misfit), effects added (--add). The replacements and
// added effects are then refitted jointly.
struct FitPlan {
  std::vector<std::pair<std::string, std::string>> replace;
  bool refit_noise = false;
  std::vector<nlohmann::json> add;  // each as a profile lists it, or {"name": ...}
};
struct FittedProfile {
  EffectChain chain;
  std::vector<ParameterMisfit> refits;  // radiometry, range noise
  std::vector<Replacement> replaced;
  std::vector<Candidate> added;
};
// Throws InputError for an effect the chain does not have or a form that cannot replace it, and
// as fit_effects does for the added ones.
FittedProfile fit_profile(const PixelTable& table, const EffectChain& chain, const FitPlan& plan,
                          const DiagnoseOptions& options = {});

}  // namespace lidartwin
