#pragma once
// The sensor's persistent state (what a real sensor keeps in flash): the saved config and the user
// data, in one JSON file written atomically.
#include <filesystem>
#include <optional>

#include <nlohmann/json.hpp>

#include "lidartwin/sensor/sensor.h"

namespace lidartwin {

struct SavedState {
  nlohmann::json config = nlohmann::json::object();
  UserData user_data;
};

// nullopt when the file does not exist yet. Throws InputError naming the file and the bad key when
// it exists but is not a state file.
std::optional<SavedState> load_state(const std::filesystem::path& path);

// Writes a temporary file next to `path`, then renames it over `path`: a crash leaves either the
// old or the new state, never a torn file. Throws std::runtime_error naming the file on failure.
void save_state(const std::filesystem::path& path, const SavedState& state);

}  // namespace lidartwin
