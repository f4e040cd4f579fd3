// Effect name -> factory. The built-in effects are listed here and registered on first use of the
// registry (see builtin_effects.h for why not from static initializers); register_effect adds
// more, e.g. from a test or a tool.
#include <algorithm>
#include <map>
#include <mutex>
#include <vector>

#include "effects/builtin_effects.h"
#include "effects/registry.h"

namespace lidartwin {
namespace {

struct Registry {
  std::mutex mutex;
  std::map<std::string, EffectFactory, std::less<>> factories;
  std::map<std::string, EffectCard, std::less<>> cards;
  std::vector<std::string> order;  // names as first registered
  void add(const std::string& name, EffectFactory factory, EffectCard card) {
    if (!factories.count(name)) order.push_back(name);
    factories.insert_or_assign(name, std::move(factory));
    cards.insert_or_assign(name, std::move(card));
  }
};

Registry& registry() {
  static Registry* instance = [] {
    auto* r = new Registry;  // never destroyed: chains may be built during static destruction
    using namespace effects_detail;
    // One line per built-in effect: its name, factory and card (each in src/effects/<effect>.cpp).
    // The order is the diagnosis' order of candidates.
    r->add("radiometry", make_radiometry, radiometry_card());
    r->add("range_noise_linear", make_range_noise_linear, range_noise_linear_card());
    r->add("range_noise_piecewise", make_range_noise_piecewise, range_noise_piecewise_card());
    r->add("signal_precision", make_signal_precision, signal_precision_card());
    r->add("signal_outliers", make_signal_outliers, signal_outliers_card());
    r->add("range_walk", make_range_walk, range_walk_card());
    r->add("incidence", make_incidence, incidence_card());
    r->add("drift", make_drift, drift_card());
    r->add("dropout", make_dropout, dropout_card());
    r->add("mixed_pixels", make_mixed_pixels, mixed_pixels_card());
    r->add("halo", make_halo, halo_card());
    r->add("range_quantization", make_range_quantization, range_quantization_card());
    r->add("beam_calibration", make_beam_calibration, beam_calibration_card());
    r->add("vibration", make_vibration, vibration_card());
    r->add("fog", make_fog, fog_card());
    r->add("false_alarms", make_false_alarms, false_alarms_card());
    r->add("shot_noise", make_shot_noise, shot_noise_card());
    r->add("range_limits", make_range_limits, range_limits_card());
    r->add("window", make_window, window_card());
    return r;
  }();
  return *instance;
}

}  // namespace

void register_effect(std::string name, EffectFactory factory, EffectCard card) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  r.add(name, std::move(factory), std::move(card));
}

void register_effect(std::string name, EffectFactory factory, std::string catalogue) {
  register_effect(std::move(name), std::move(factory), EffectCard{.catalogue = std::move(catalogue)});
}

std::optional<EffectCard> effect_card(std::string_view name) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  const auto found = r.cards.find(name);
  if (found == r.cards.end()) return std::nullopt;
  return found->second;
}

std::optional<std::string> effect_catalogue(std::string_view name) {
  const std::optional<EffectCard> card = effect_card(name);
  if (!card) return std::nullopt;
  return card->catalogue;
}

std::vector<std::string> registered_effects() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  std::vector<std::string> names;
  for (const auto& [name, factory] : r.factories) names.push_back(name);
  return names;  // sorted: the map is ordered
}

std::vector<std::string> candidate_effects() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  std::vector<std::string> names;
  for (const std::string& name : r.order) {
    if (r.cards.at(name).candidate) names.push_back(name);
  }
  return names;
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
