#pragma once
// The ordered list of effects a profile names, built through the registry.
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect.h"
#include "lidartwin/effects/effect_card.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin {

// Registry: effect name -> factory from its JSON parameters, which sit at `at` (the input and the
// effect object's JSON pointer in it). A factory throws InputError naming `at`'s child, the key and
// the allowed range for a missing, unknown or out-of-range parameter (json_reader's Location::fail).
using EffectFactory =
    std::function<std::unique_ptr<Effect>(const nlohmann::json& params, const json_reader::Location& at)>;
// card: what the analysis knows of it (effect_card.h): its catalogue id, so reports can name the
// physics, and whether and how the diagnosis fits it. Registering a name again replaces it.
void register_effect(std::string name, EffectFactory factory, EffectCard card);
// catalogue: the effect's id in lidar-physics.md's catalogue ("E4"); empty for effects outside it.
// Not a candidate of the diagnosis; `fit --add` fits it when the id is empty.
void register_effect(std::string name, EffectFactory factory, std::string catalogue = "");
// The card an effect was registered with; nullopt for an unknown name.
std::optional<EffectCard> effect_card(std::string_view name);
// Its catalogue id ("" if none); nullopt for an unknown name.
std::optional<std::string> effect_catalogue(std::string_view name);
std::vector<std::string> registered_effects();  // sorted by name
// The effects whose card makes them the diagnosis' candidates, in the order they were registered
// (the built-in ones in the registry's order, then others as registered).
std::vector<std::string> candidate_effects();

class EffectChain {
 public:
  EffectChain() = default;
  // document: [{"name": "range_noise_linear", "sigma0_m": 0.01, ...}, ...], found at `at`: the
  // file and the array's JSON pointer, {"profiles/os1-64.json", "/effects"}, so that errors read
  // "profiles/os1-64.json: /effects/2/sigma0_m: must be in [0, 1], got -0.01". Each effect gets a
  // stream id from its name and position; an effect's prerequisites must come earlier.
  static EffectChain from_json(const nlohmann::json& document, const json_reader::Location& at);
  // The same for an input whose whole document is the array ("--add", "test": "test: /2/sigma0_m").
  static EffectChain from_json(const nlohmann::json& document, std::string_view source) {
    return from_json(document, json_reader::Location{std::string(source), ""});
  }
  nlohmann::json to_json() const;

  // Measurement from ideal returns (range = ideal range, 0 if no hit), then each effect in order.
  // One virtual call per effect per column; effects loop over the beams. out.size() == ideal.size().
  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context, MeasuredColumn& out) const;
  // The same, one struct per pixel (tests and analysis; the renderer uses the arrays above).
  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context, std::span<Measurement> out) const;
  // Bias 0, variance 0, p_detect = hit ? 1 : 0, then each effect folds itself in, in order.
  Prediction predict(const IdealReturn& ideal, const ColumnContext& context) const;

  const std::vector<std::shared_ptr<const Effect>>& effects() const { return effects_; }
  // Whether any effect reads the ideal returns' edge partners (the caster finds them only then).
  bool needs_edge_partners() const;
  // Whether any effect moves the sensor (E11), and the pose a column is then cast from: each such
  // effect's moved_pose in chain order.
  bool moves_sensor() const;
  Pose moved_pose(const Pose& world_from_sensor, const ColumnContext& context) const;
  // Copies of `effect` placed at the end or at `index`, with that position's stream id.
  EffectChain with_effect(std::shared_ptr<const Effect> effect) const;  // appended
  EffectChain replacing(size_t index, std::shared_ptr<const Effect> effect) const;

 private:
  std::vector<std::shared_ptr<const Effect>> effects_;
};

}  // namespace lidartwin
