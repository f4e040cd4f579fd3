#pragma once
// What the diagnosis, `fit` and the noise-law replacements share: an effect's free parameters fitted
// by maximum likelihood on the pixel table (lidar-physics.md 3.5), wherever the effect sits in the
// chain (a candidate added, a profile's own effect refitted in place, or put in another's place).
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/pixel_table.h"
#include "lidartwin/analysis/unexplained.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/frame/worker_pool.h"

namespace lidartwin::analysis_detail {

// A parameter a fit moves (the effect's card, effect_card.h, gives a candidate's).
using FreeParameter = FitStart;
struct CandidateSpec {
  std::string effect;
  std::vector<FreeParameter> free;
  nlohmann::json start = nullptr;  // the effect as it starts (fixed parameters included); null: defaults
};

// What the search tries: each registered effect whose card makes it a candidate, with the
// parameters its card fits, in the registry's order.
std::vector<CandidateSpec> candidate_specs();
// The candidate named `effect`; nullopt for an effect that is none.
std::optional<CandidateSpec> candidate_spec(std::string_view effect);

// A parameter's place in its effect's JSON: a key, or a path below it ("points_m/2/1").
nlohmann::json::json_pointer pointer(const std::string& name);

// What a profile's own effect refits in place (parameter misfit): a candidate's free parameters,
// or, with range_noise, the range noise's sigmas (E1).
std::optional<CandidateSpec> refit_spec(const Effect& effect, bool range_noise);

// The pixels a fit scores (rows of the table), and the workers that sum their likelihood: each
// evaluation is summed in fixed chunks of rows, added in order, so the sum is the same whatever
// the pool's size (none: the calling thread alone).
//
// Each row's inputs are gathered from the table once, in row order: an evaluation reads them
// front to back, where from the table (an array per input, the rows every k-th pixel) each input
// costs its own cache line every few rows. That saved about 7 % of a diagnosis' CPU; the rest is
// per-row arithmetic: each row's model (the effects after the fitted one, range_model), scalar,
// then its likelihood, the common case in a SIMD kernel (pixel_nlls).
struct FitRow {
  IdealReturn ideal;
  PixelTable::ModelInputs model;
  float range_m = 0.0f;  // measured
  uint32_t column = 0;
  uint64_t frame = 0;
  double time_s = 0.0;  // since the capture's start, as context_of gives it
  ColumnContext context(const PixelTable& t) const {
    ColumnContext c = t.context;
    c.frame = frame;
    c.column = column;
    c.time_s = time_s;
    return c;
  }
};
struct FitRows {
  std::vector<size_t> index;
  WorkerPool* pool = nullptr;
  std::vector<FitRow> inputs;  // per entry of index
  size_t size() const { return index.size(); }
  size_t operator[](size_t k) const { return index[k]; }
  auto begin() const { return index.begin(); }
  auto end() const { return index.end(); }
};

// The fitted pixels: an even subsample of up to max_pixels of those that meet a surface.
FitRows subsample(const PixelTable& t, size_t max_pixels, WorkerPool* pool);

// Total NLL of the rows under a chain (the same likelihood compare scores with).
// adjust: a misfit pattern's per-bin values applied on top of the chain's predictions.
double total_nll(const PixelTable& t, const FitRows& rows, const EffectChain& chain,
                 const PatternAdjustment* adjust = nullptr);

// What a chain's first `count` effects predict for each of the rows: a fit changes one effect and
// evaluates the chain hundreds of times, and the effects before it predict the same every time
// (about a fifth of the diagnosis' time). count 0: nothing kept.
class SharedPrefix {
 public:
  SharedPrefix() = default;
  SharedPrefix(const PixelTable& t, const FitRows& rows, const EffectChain& chain, size_t count);
  size_t count() const { return count_; }
  const Prediction& operator[](size_t row) const { return predictions_[row]; }

 private:
  size_t count_ = 0;
  std::vector<Prediction> predictions_;  // per entry of rows
};

// total_nll of a chain whose first prefix.count() effects are those the prefix was predicted with.
double total_nll(const PixelTable& t, const FitRows& rows, const EffectChain& chain, const SharedPrefix& prefix,
                 const PatternAdjustment* adjust = nullptr);
// The same, row by row (the terms total_nll adds): the robust intervals' per-pixel scores.
std::vector<double> row_nlls(const PixelTable& t, const FitRows& rows, const EffectChain& chain,
                             const SharedPrefix& prefix, const PatternAdjustment* adjust = nullptr);

// The chain with `effect` inserted before its range limits (what limits the window must see the
// shifted range), or appended.
EffectChain with_candidate(const EffectChain& chain, const nlohmann::json& effect);

// Where a fitted effect goes: a candidate joins the chain before its range limits; a profile's own
// effect being refitted (`index`) keeps its place, its other parameters and its random streams; a
// replacement (`index` and `replaces`) takes the place of the effect there, starting from its spec.
struct Placement {
  const EffectChain& base;
  std::optional<size_t> index;  // none: a candidate
  bool replaces = false;
  EffectChain chain_with(const nlohmann::json& effect) const;
  // The effect as it starts: the spec's (defaults, or its start), or the profile's own.
  nlohmann::json start(const CandidateSpec& spec) const;
  bool refits() const { return index && !replaces; }
  // The first effect of the chain that differs from `base` as the fitted effect's values change.
  size_t first_changed() const;
};

// The likelihood-ratio test, BIC and catalogue id of a candidate with k free parameters.
void score_candidate(Candidate& c, double base_nll, double nll, double k, size_t n);

// Whether a fit computes its parameters' intervals: a quarter of a diagnosis' likelihood
// evaluations (the Hessian's and the sandwich's), wasted on the many fits that only compare BICs
// (later rounds' candidates, a joint refit's passes before the last). Without, they are NaN.
enum class Intervals { kWith, kWithout };

// The spec's free parameters fitted at `place` (NLopt BOBYQA, restarted while it still gains), from
// the chain's NLL base_nll; scored with k = its free parameters, 95 % intervals from the curvature,
// and robust ones from the sandwich (FittedParameter).
Candidate fit(const PixelTable& t, const FitRows& rows, const Placement& place, double base_nll,
              const CandidateSpec& spec, const PatternAdjustment* adjust = nullptr,
              Intervals intervals = Intervals::kWith);

// The intervals of a candidate fitted without them, at its values, placed at `place`.
void add_intervals(const PixelTable& t, const FitRows& rows, const Placement& place, const CandidateSpec& spec,
                   Candidate& c);

// Each of `fitted` (effects in `chain`, found by name) refitted in its place given all the others,
// in turn, until a pass gains less than 0.1 nats; chain, nll and the candidates are updated (their
// intervals are not: refit_jointly adds them).
void refit_in_turn(const PixelTable& t, const FitRows& rows, EffectChain& chain, double& nll,
                   const std::vector<Candidate*>& fitted, const std::vector<CandidateSpec>& specs);

// refit_in_turn, then each one's intervals given the others' final values.
void refit_jointly(const PixelTable& t, const FitRows& rows, EffectChain& chain, double& nll,
                   std::vector<Candidate*> fitted, const std::vector<CandidateSpec>& specs);

// A profile's own effect (at `index`) refitted in place from its values, kept (returned) where the
// refit is very strong evidence (delta BIC > options.min_delta_bic) and significant at `alpha`;
// chain and nll then updated.
std::optional<ParameterMisfit> refit_in_place(const PixelTable& t, const FitRows& rows, EffectChain& chain, double& nll,
                                              size_t index, const CandidateSpec& spec, const DiagnoseOptions& options,
                                              double alpha);

// An effect the search does not list (one a user registered): every parameter that is not fixed is
// fitted, from the value `effect` gives it (or its default), in steps of a tenth of its bounds.
CandidateSpec spec_of(const nlohmann::json& effect);

}  // namespace lidartwin::analysis_detail
