#pragma once
// What the analysis must know of an effect beyond its parameters (Effect::parameters lists those
// with their bounds): its place in lidar-physics.md's catalogue, how a fit starts and steps it,
// and what a comparison without the scene's surfaces can see of it. Each effect writes its card
// next to its parameter table (src/effects/<effect>.cpp), and register_effect takes the card with
// the factory: adding an effect touches src/effects/ and the registry, nothing in the analysis.
#include <limits>
#include <string>
#include <vector>

namespace lidartwin {

// A parameter a fit moves: its starting value and the scale of a first step (NLopt's BOBYQA works
// in these units).
struct FitStart {
  std::string name = {};  // EffectParameter::name
  double start = 0.0;
  double step = 0.0;
  // Other parameters that take the same value (a datasheet table's plateau is two knots, one sigma).
  std::vector<std::string> tied = {};
  // Below the effect's own upper bound, where a search needs it (the fit's own bound).
  double most = std::numeric_limits<double>::infinity();
};

struct EffectCard {
  std::string catalogue = {};  // lidar-physics.md's id ("E4"); "" outside the catalogue
  // Which part of a catalogue entry the effect models, where two effects share one entry or it has
  // none ("E16's window part"); "" where the id says it.
  std::string note = {};
  // Whether the diagnosis tries it as a missing effect, fitting `fit` (the other parameters at
  // their defaults). `fit --add` fits the same.
  bool candidate = false;
  std::vector<FitStart> fit = {};
  // Whether a profile's own instance is refitted in place where the profile misfits (its `fit`,
  // and `refit_also` beside them), or only ever fitted as a missing effect.
  bool refit_in_place = true;
  std::vector<FitStart> refit_also = {};
  // Whether a reference made of the capture itself, a pixel's temporal mean (compare --static), can
  // show it: not where the effect is a bias that holds between frames, or needs the scene's
  // surfaces to be placed (depth edges, retroreflectors, a surface's tilt). Fitted there, such an
  // effect could only come out at nothing: the diagnosis does not try it.
  bool seen_against_temporal_mean = true;
};

}  // namespace lidartwin
