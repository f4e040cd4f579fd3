#pragma once
// The shipped datasheet profiles' chain without the physical effects they enable beyond Table I
// (incidence, E4; signal-driven detection, E5): radiometry, the datasheet's sigma(r), range limits
// and quantization. The baseline of the fingerprint and analysis tests, which add one effect to it
// and look for that effect alone. (Its own namespace: cli_compare_test has a function named
// lidartwin.)
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
    if (effect.at("name") != "incidence" && effect.at("name") != "dropout") kept.push_back(effect);
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

}  // namespace table_profiles
