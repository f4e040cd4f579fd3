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
  std::map<std::string, std::string, std::less<>> catalogue;  // name -> lidar-physics.md id
  void add(const std::string& name, EffectFactory factory, std::string id) {
    factories.insert_or_assign(name, std::move(factory));
    catalogue.insert_or_assign(name, std::move(id));
  }
};

Registry& registry() {
  static Registry* instance = [] {
    auto* r = new Registry;  // never destroyed: chains may be built during static destruction
    using namespace effects_detail;
    // One line per built-in effect: name, factory, catalogue id (lidar-physics.md section 1).
    r->add("radiometry", make_radiometry, "");  // section 2.2: the channels, not a range error
    r->add("range_noise_linear", make_range_noise_linear, "E1");
    r->add("range_noise_piecewise", make_range_noise_piecewise, "E1");
    r->add("signal_precision", make_signal_precision, "E2");
    r->add("signal_outliers", make_signal_outliers, "E2");
    r->add("range_walk", make_range_walk, "E3");
    r->add("incidence", make_incidence, "E4");
    r->add("dropout", make_dropout, "E5");
    r->add("mixed_pixels", make_mixed_pixels, "E6");
    r->add("halo", make_halo, "E8");
    r->add("range_quantization", make_range_quantization, "E9");
    r->add("beam_calibration", make_beam_calibration, "E10");
    r->add("vibration", make_vibration, "E11");
    r->add("drift", make_drift, "E12");
    r->add("fog", make_fog, "E13");
    r->add("false_alarms", make_false_alarms, "E14");
    r->add("shot_noise", make_shot_noise, "");  // section 2.2: the channels, not a range error
    r->add("range_limits", make_range_limits, "E16");
    r->add("window", make_window, "E16");
    return r;
  }();
  return *instance;
}

}  // namespace

void register_effect(std::string name, EffectFactory factory, std::string catalogue) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  r.add(name, std::move(factory), std::move(catalogue));
}

std::optional<std::string> effect_catalogue(std::string_view name) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  const auto found = r.catalogue.find(name);
  if (found == r.catalogue.end()) return std::nullopt;
  return found->second;
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
