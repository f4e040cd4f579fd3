// The ordered effect list of a profile: built from JSON through the registry, applied in order.
#include "lidartwin/effects/effect_chain.h"

#include <algorithm>
#include <cassert>

#include <fmt/ranges.h>

#include "effects/parameters.h"
#include "effects/registry.h"
#include "lidartwin/random/counter_rng.h"

namespace lidartwin {
namespace {

using json_reader::Location;

// Each effect draws from its own streams, keyed by its name and place in the chain (FNV-1a of
// the name, mixed with the position), so adding or refitting one effect leaves the others' noise
// unchanged wherever they still sit.
uint32_t stream_id_for(std::string_view name, size_t position) {
  uint64_t hash = 0xCBF29CE484222325ULL;
  for (const char c : name) hash = (hash ^ static_cast<unsigned char>(c)) * 0x100000001B3ULL;
  return static_cast<uint32_t>(rng_detail::mix64(hash + position) >> 32);
}

// A copy of `effect` carrying the stream id of `position` (effects are shared and immutable).
std::shared_ptr<const Effect> placed(const Effect& effect, size_t position) {
  std::vector<double> values;
  for (const auto& parameter : effect.parameters()) values.push_back(parameter.value);
  std::unique_ptr<Effect> copy = effect.with_parameters(values);
  copy->set_stream_id(stream_id_for(effect.name(), position));
  return copy;
}

std::string registered_list() { return fmt::format("{}", fmt::join(registered_effects(), ", ")); }

std::unique_ptr<Effect> build_effect(const nlohmann::json& element, const Location& at) {
  if (!element.is_object()) at.fail_expected("an effect object {\"name\": ..., <parameters>}", element);
  const auto name = element.find("name");
  if (name == element.end()) at.child("name").fail("missing; registered effects: " + registered_list());
  if (!name->is_string()) at.child("name").fail_expected("a string, one of: " + registered_list(), *name);
  const auto factory = effects_detail::find_effect(name->get<std::string>());
  if (!factory) {
    at.child("name").fail("unknown effect \"" + name->get<std::string>() +
                          "\"; registered effects: " + registered_list());
  }
  return (*factory)(element, at);
}

// An effect's prerequisites must sit earlier in the chain.
void check_order(const std::vector<std::shared_ptr<const Effect>>& effects, const Location& at) {
  for (size_t i = 0; i < effects.size(); ++i) {
    for (const auto needed : effects[i]->prerequisites()) {
      const bool before = std::any_of(effects.begin(), effects.begin() + static_cast<std::ptrdiff_t>(i),
                                      [&](const auto& e) { return e->name() == needed; });
      if (!before) {
        at.child(i).fail(std::string(effects[i]->name()) + " needs " + std::string(needed) + " earlier in the chain");
      }
    }
  }
}

}  // namespace

EffectChain EffectChain::from_json(const nlohmann::json& document, const Location& at) {
  if (!document.is_array()) at.fail_expected("an array of effects [{\"name\": ...}, ...]", document);
  EffectChain chain;
  for (size_t i = 0; i < document.size(); ++i) {
    const Location where = at.child(i);
    // "source": where the effect's parameters came from (a datasheet, a fit on a capture): for
    // people, not for the effect, which never sees it.
    nlohmann::json params = document[i];
    if (params.is_object()) {
      if (const auto origin = params.find("source"); origin != params.end()) {
        if (!origin->is_string()) {
          where.child("source").fail_expected("a string (where the parameters came from)", *origin);
        }
        params.erase(origin);
      }
    }
    std::unique_ptr<Effect> effect = build_effect(params, where);
    effect->set_stream_id(stream_id_for(effect->name(), i));
    chain.effects_.push_back(std::move(effect));
  }
  check_order(chain.effects_, at);
  return chain;
}

nlohmann::json EffectChain::to_json() const {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& effect : effects_) out.push_back(effect->to_json());
  return out;
}

void EffectChain::simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                           MeasuredColumn& out) const {
  assert(ideal.size() == out.size());
  for (size_t i = 0; i < ideal.size(); ++i) out.range_m[i] = ideal[i].hit() ? ideal[i].range_m : 0.0f;
  for (auto* quantity : {&out.signal_photons, &out.near_ir_photons, &out.reflectivity, &out.range2_m,
                         &out.signal2_photons, &out.reflectivity2}) {
    std::fill(quantity->begin(), quantity->end(), 0.0f);
  }
  out.list_returns();
  for (const auto& effect : effects_) {
    effect->simulate(ideal, context, out);
    if (effect->adds_returns()) out.list_returns();
  }
}

void EffectChain::simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                           std::span<Measurement> out) const {
  assert(ideal.size() == out.size());
  MeasuredColumn column(ideal.size());
  simulate(ideal, context, column);
  for (size_t i = 0; i < out.size(); ++i) out[i] = column[i];
}

Prediction EffectChain::predict(const IdealReturn& ideal, const ColumnContext& context) const {
  Prediction prediction;
  prediction.p_detect = ideal.hit() ? 1.0 : 0.0;
  for (const auto& effect : effects_) effect->predict(ideal, context, prediction);
  return prediction;
}

bool EffectChain::needs_edge_partners() const {
  return std::any_of(effects_.begin(), effects_.end(), [](const auto& e) { return e->needs_edge_partners(); });
}

bool EffectChain::moves_sensor() const {
  return std::any_of(effects_.begin(), effects_.end(), [](const auto& e) { return e->moves_sensor(); });
}

Pose EffectChain::moved_pose(const Pose& world_from_sensor, const ColumnContext& context) const {
  Pose pose = world_from_sensor;
  for (const auto& effect : effects_) {
    if (effect->moves_sensor()) pose = effect->moved_pose(pose, context);
  }
  return pose;
}

EffectChain EffectChain::with_effect(std::shared_ptr<const Effect> effect) const {
  EffectChain chain = *this;
  chain.effects_.push_back(placed(*effect, chain.effects_.size()));
  check_order(chain.effects_, Location{"effect chain", ""});
  return chain;
}

EffectChain EffectChain::replacing(size_t index, std::shared_ptr<const Effect> effect) const {
  assert(index < effects_.size());
  EffectChain chain = *this;
  chain.effects_.at(index) = placed(*effect, index);
  check_order(chain.effects_, Location{"effect chain", ""});
  return chain;
}

}  // namespace lidartwin
