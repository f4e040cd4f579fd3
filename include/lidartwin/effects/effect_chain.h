#pragma once
// The ordered list of effects a profile names, built through the registry.
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect.h"

namespace lidartwin {

// Registry: effect name -> factory from its JSON parameters. A factory throws InputError naming
// `source`, the key and the allowed range for a missing, unknown or out-of-range parameter.
using EffectFactory = std::function<std::unique_ptr<Effect>(const nlohmann::json& params, std::string_view source)>;
void register_effect(std::string name, EffectFactory factory);
std::vector<std::string> registered_effects();

class EffectChain {
 public:
  EffectChain() = default;
  // document: [{"name": "range_noise_linear", "sigma0_m": 0.01, ...}, ...]. source names the file
  // (and JSON path) for error messages, e.g. "profiles/os1-64.json: /effects/2/sigma_m: ...".
  static EffectChain from_json(const nlohmann::json& document, std::string_view source);
  nlohmann::json to_json() const;

  // Measurement from ideal returns, then each effect in order.
  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context, std::span<Measurement> out) const;
  Prediction predict(const IdealReturn& ideal, const ColumnContext& context) const;

  const std::vector<std::shared_ptr<const Effect>>& effects() const { return effects_; }
  EffectChain with_effect(std::shared_ptr<const Effect> effect) const;       // appended
  EffectChain replacing(size_t index, std::shared_ptr<const Effect> effect) const;

 private:
  std::vector<std::shared_ptr<const Effect>> effects_;
};

}  // namespace lidartwin
