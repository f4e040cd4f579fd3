// Finding and reading profile files: a bare name is looked up in profiles_dir(), anything that
// looks like a path is read as given.
#include <algorithm>
#include <cstdlib>
#include <fstream>

#include <fmt/ranges.h>

#include "lidartwin/error.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin {
namespace {

bool looks_like_path(std::string_view name) {
  return name.find('/') != std::string_view::npos || name.ends_with(".json");
}

std::string list_available() {
  const std::vector<std::string> names = available_profiles();
  return names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", "));
}

nlohmann::json read_json(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open profile file");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path.string() + ": not valid JSON: " + e.what());
  }
}

}  // namespace

std::filesystem::path source_dir() {
  if (const char* source = std::getenv("LIDARTWIN_SOURCE_DIR"); source != nullptr && *source != '\0') return source;
  return LIDARTWIN_SOURCE_DIR;
}

std::filesystem::path profiles_dir() {
  if (const char* overridden = std::getenv("LIDARTWIN_PROFILES"); overridden != nullptr && *overridden != '\0') {
    return overridden;
  }
  return source_dir() / "profiles";
}

std::vector<std::string> available_profiles() {
  std::vector<std::string> names;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(profiles_dir(), error)) {
    if (entry.path().extension() == ".json") names.push_back(entry.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::filesystem::path profile_file(std::string_view name_or_path) {
  std::filesystem::path path(name_or_path);
  if (!looks_like_path(name_or_path)) {
    path = profiles_dir() / (std::string(name_or_path) + ".json");
    if (!std::filesystem::exists(path)) {
      throw InputError("profile \"" + std::string(name_or_path) + "\": no " + path.string() +
                       "; available: " + list_available());
    }
  }
  return path;
}

SensorProfile load_profile(std::string_view name_or_path) {
  const std::filesystem::path path = profile_file(name_or_path);
  return parse_profile(read_json(path), path.string());
}

std::optional<nlohmann::json> datasheet_range_noise(std::string_view prod_line) {
  // The family: the first two fields of the product line ("OS-1").
  const auto family = [](std::string_view line) {
    const size_t second = line.find('-', line.find('-') + 1);
    return line.substr(0, second);
  };
  for (const std::string& name : available_profiles()) {
    SensorProfile profile;
    try {
      profile = load_profile(name);
    } catch (const InputError&) {  // a broken file in $LIDARTWIN_PROFILES is not this search's to report
      continue;
    }
    if (family(profile.prod_line) != family(prod_line)) continue;
    for (const nlohmann::json& effect : profile.effects) {
      if (effect.value("name", "") == "range_noise_piecewise") return effect;
    }
  }
  return std::nullopt;
}

}  // namespace lidartwin
