// Persisted config and user data (protocol doc 2.7 "persist"; on a real sensor: flash).
#include "sensor/state_file.h"

#include <unistd.h>

#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin {
namespace {

constexpr int kFormatVersion = 1;

// Unknown keys are kept (ignored): a newer lidartwin may add some to the file it writes.
SavedState parse_state(const nlohmann::json& document, const std::string& source) {
  const json_reader::Location root{source, ""};
  if (!document.is_object() || document.value("lidartwin_state", nlohmann::json()) != kFormatVersion) {
    root.fail("not a lidartwin state file (expected \"lidartwin_state\": " + std::to_string(kFormatVersion) + ")");
  }
  const json_reader::ObjectReader reader(document, root, {}, json_reader::UnknownKeys::kKeep);
  SavedState state;
  const auto& config = reader.at("config", "a JSON object of config keys");
  if (!config.is_object()) reader.child("config").fail_expected("a JSON object of config keys", config);
  state.config = config;
  if (const auto* value = reader.find("user_data")) {
    state.user_data.value = json_reader::read_string(*value, reader.child("user_data"));
  }
  if (const auto* policy = reader.find("user_data_policy")) {
    const auto parsed = policy->is_string() ? user_data_policy_from_string(policy->get<std::string>()) : std::nullopt;
    if (!parsed) {
      reader.child("user_data_policy")
          .fail_expected("\"keep_on_config_delete\" or \"clear_on_config_delete\"", *policy);
    }
    state.user_data.policy = *parsed;
  }
  return state;
}

}  // namespace

std::optional<SavedState> load_state(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    if (!std::filesystem::exists(path)) return std::nullopt;
    throw InputError(path.string() + ": cannot be read");
  }
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path.string() + ": not valid JSON: " + e.what());
  }
  return parse_state(document, path.string());
}

void save_state(const std::filesystem::path& path, const SavedState& state) {
  const nlohmann::json document = {
      {"lidartwin_state", kFormatVersion},
      {"config", state.config},
      {"user_data", state.user_data.value},
      {"user_data_policy", std::string(to_string(state.user_data.policy))},
  };
  // Same directory, so the rename stays on one file system and is atomic.
  auto temporary = path;
  temporary += ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << document.dump(2) << '\n';
    out.flush();
    if (!out) throw std::runtime_error(temporary.string() + ": cannot write the sensor state");
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    const auto reason = error.message();
    std::filesystem::remove(temporary, error);
    throw std::runtime_error(path.string() + ": cannot save the sensor state: " + reason);
  }
}

}  // namespace lidartwin
