#pragma once
// The registry's lookup, for EffectChain (the public half is in effect_chain.h).
#include <optional>
#include <string_view>

#include "lidartwin/effects/effect_chain.h"

namespace lidartwin::effects_detail {

// A copy of the factory registered under `name`, or nullopt.
std::optional<EffectFactory> find_effect(std::string_view name);

}  // namespace lidartwin::effects_detail
