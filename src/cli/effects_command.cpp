// `lidartwin effects`: the effect library as a profile author needs it: each registered effect's
// lidar-physics.md catalogue id, what must come before it in a chain, and its parameters with
// their defaults and bounds (--json for scripts). The values are read from the effects
// themselves, built with their defaults, so this list cannot drift from the code.
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "cli/command.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin::cli {
namespace {

using json_reader::format_number;

// One effect as documented: built alone with its defaults (after radiometry when it needs it).
// Effects without defaults for some parameters (a sigma(r) law) report what they require.
nlohmann::json describe_effect(const std::string& name) {
  const EffectCard card = effect_card(name).value_or(EffectCard{});
  nlohmann::json entry = {{"name", name}, {"catalogue", card.catalogue}};
  if (!card.note.empty()) entry["note"] = card.note;
  if (card.candidate) {
    nlohmann::json fitted = nlohmann::json::array();
    for (const FitStart& p : card.fit) fitted.push_back(p.name);
    entry["diagnosis_fits"] = fitted;  // the parameters the diagnosis fits when it tries the effect
  }
  nlohmann::json chain = nlohmann::json::array();
  if (name != "radiometry") chain.push_back({{"name", "radiometry"}});
  chain.push_back({{"name", name}});
  try {
    const EffectChain built = EffectChain::from_json(chain, "defaults of " + name);
    const Effect& effect = *built.effects().back();
    nlohmann::json parameters = nlohmann::json::array();
    for (const EffectParameter& p : effect.parameters()) {
      parameters.push_back({{"name", p.name}, {"default", p.value}, {"lower", p.lower}, {"upper", p.upper}});
    }
    entry["parameters"] = parameters;
    nlohmann::json prerequisites = nlohmann::json::array();
    for (const std::string_view before : effect.prerequisites()) prerequisites.push_back(std::string(before));
    entry["prerequisites"] = prerequisites;
  } catch (const InputError& e) {
    // "defaults of range_noise_linear: /1/sigma0_m: missing; ..." -> "sigma0_m: missing; ..."
    const std::string message = e.what();
    const size_t at = message.find(": /1/");
    entry["requires"] = at == std::string::npos ? message : message.substr(at + 5);
  }
  return entry;
}

void print_table(const nlohmann::json& effects) {
  for (const nlohmann::json& e : effects) {
    const std::string catalogue = e["catalogue"].get<std::string>();
    std::printf("%s%s\n", e["name"].get<std::string>().c_str(),
                catalogue.empty() ? "" : fmt::format(" ({})", catalogue).c_str());
    if (e.contains("note")) std::printf("    %s\n", e["note"].get<std::string>().c_str());
    if (e.contains("diagnosis_fits")) {
      const auto fits = e["diagnosis_fits"].get<std::vector<std::string>>();
      std::printf("    compare --diagnose tries it as a missing effect, fitting %s\n",
                  fits.empty() ? "it in closed form" : fmt::format("{}", fmt::join(fits, ", ")).c_str());
    }
    if (e.contains("requires")) {
      std::printf("    needs values: %s\n", e["requires"].get<std::string>().c_str());
      continue;
    }
    if (!e["prerequisites"].empty()) {
      std::printf("    after: %s\n",
                  fmt::format("{}", fmt::join(e["prerequisites"].get<std::vector<std::string>>(), ", ")).c_str());
    }
    for (const nlohmann::json& p : e["parameters"]) {
      std::printf("    %-28s %-14s in [%s, %s]\n", p["name"].get<std::string>().c_str(),
                  format_number(p["default"].get<double>()).c_str(), format_number(p["lower"].get<double>()).c_str(),
                  format_number(p["upper"].get<double>()).c_str());
    }
  }
}

void setup_effects(CLI::App& app, std::function<int()>& run) {
  auto as_json = std::make_shared<bool>(false);
  CLI::App* sub = app.add_subcommand(
      "effects", "List the effect library: catalogue ids, prerequisites, parameters with defaults and bounds");
  sub->add_flag("--json", *as_json, "print JSON (an array, one object per effect) instead of a table");
  sub->callback([&run, as_json] {
    run = [as_json] {
      nlohmann::json effects = nlohmann::json::array();
      for (const std::string& name : registered_effects()) effects.push_back(describe_effect(name));
      if (*as_json) {
        std::printf("%s\n", effects.dump(2).c_str());
      } else {
        print_table(effects);
      }
      return 0;
    };
  });
}

const RegisterCommand registered_effects("effects", setup_effects);

}  // namespace
}  // namespace lidartwin::cli
