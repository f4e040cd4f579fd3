#pragma once
// The shipped datasheet profiles' chain without the physical effects they enable beyond Table I
// (mixed pixels, E6; incidence, E4; signal-driven detection, E5; signal-dependent precision, E2, and
// its tails):
// radiometry, the datasheet's sigma(r), range limits and quantization. The baseline of the fingerprint and analysis
// tests, which add one effect to it and look for that effect alone. (Its own namespace: cli_compare_test has a function
// named lidartwin.)
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace table_profiles {

inline void keep_table_effects(nlohmann::json& effects) {
  nlohmann::json kept = nlohmann::json::array();
  for (const auto& effect : effects) {
    const auto& name = effect.at("name");
    if (name != "incidence" && name != "dropout" && name != "signal_precision" && name != "signal_outliers" &&
        name != "mixed_pixels") {
      kept.push_back(effect);
    }
  }
  effects = kept;
}

// profiles/<shipped>.json with its table effects only, as <temporary directory>/table_<pid>/
// <shipped>.json: the same file stem, so reports still name the profile <shipped>.
inline std::filesystem::path table_profile(const std::string& shipped) {
  const auto dir = std::filesystem::path(testing::TempDir()) / ("table_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ifstream in(std::string(LIDARTWIN_SOURCE_DIR) + "/profiles/" + shipped + ".json");
  nlohmann::json profile = nlohmann::json::parse(in);
  keep_table_effects(profile.at("effects"));
  const auto path = dir / (shipped + ".json");
  std::ofstream(path) << profile.dump(2);
  return path;
}

// profiles/<shipped>.json as it was before real captures refitted it: without E2 (and its tails) and E6, the
// radiometry's default ambient light and the incidence effect at the datasheet's divergence. What a
// user of the datasheet alone would compare real data with (the "old table").
inline std::filesystem::path datasheet_only_profile(const std::string& shipped) {
  const auto dir = std::filesystem::path(testing::TempDir()) / ("datasheet_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ifstream in(std::string(LIDARTWIN_SOURCE_DIR) + "/profiles/" + shipped + ".json");
  nlohmann::json profile = nlohmann::json::parse(in);
  nlohmann::json kept = nlohmann::json::array();
  for (const auto& effect : profile.at("effects")) {
    const auto& name = effect.at("name");
    if (name == "signal_precision" || name == "signal_outliers" || name == "mixed_pixels") continue;
    if (name == "radiometry") {
      kept.push_back({{"name", "radiometry"}});
    } else if (name == "incidence") {
      kept.push_back({{"name", "incidence"}, {"divergence_rad", profile.at("beam_divergence_rad")}});
    } else {
      kept.push_back(effect);
    }
  }
  profile["effects"] = kept;
  const auto path = dir / (shipped + ".json");
  std::ofstream(path) << profile.dump(2);
  return path;
}

}  // namespace table_profiles
