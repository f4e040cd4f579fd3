// Effect name -> factory. The built-in effects are listed here and registered on first use of the
// registry (see builtin_effects.h for why not from static initializers); register_effect adds
// more, e.g. from a test or a tool.
#include <algorithm>
#include <map>
#include <mutex>

#include "effects/builtin_effects.h"
#include "effects/registry.h"

namespace lidartwin {
namespace {

struct Registry {
  std::mutex mutex;
  std::map<std::string, EffectFactory, std::less<>> factories;
};

Registry& registry() {
  static Registry* instance = [] {
    auto* r = new Registry;  // never destroyed: chains may be built during static destruction
    using namespace effects_detail;
    r->factories.emplace("radiometry", make_radiometry);
    r->factories.emplace("range_noise_linear", make_range_noise_linear);
    r->factories.emplace("range_noise_piecewise", make_range_noise_piecewise);
    r->factories.emplace("range_limits", make_range_limits);
    r->factories.emplace("range_quantization", make_range_quantization);
    r->factories.emplace("dropout", make_dropout);
    r->factories.emplace("incidence", make_incidence);
    r->factories.emplace("beam_calibration", make_beam_calibration);
    return r;
  }();
  return *instance;
}

}  // namespace

void register_effect(std::string name, EffectFactory factory) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  r.factories.insert_or_assign(std::move(name), std::move(factory));
}

std::vector<std::string> registered_effects() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  std::vector<std::string> names;
  for (const auto& [name, factory] : r.factories) names.push_back(name);
  return names;  // sorted: the map is ordered
}

namespace effects_detail {

std::optional<EffectFactory> find_effect(std::string_view name) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  const auto found = r.factories.find(name);
  if (found == r.factories.end()) return std::nullopt;
  return found->second;
}

}  // namespace effects_detail
}  // namespace lidartwin
