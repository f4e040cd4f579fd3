// The part of Effect shared by every effect.
#include "lidartwin/effects/effect.h"

namespace lidartwin {

// Parameter names are JSON pointers below the effect's object, so structured parameters such as
// range_noise_piecewise's "points_m/2/1" rebuild their arrays here (listed in index order).
nlohmann::json Effect::to_json() const {
  nlohmann::json out = nlohmann::json::object();
  out["name"] = std::string(name());
  for (const auto& parameter : parameters()) {
    out[nlohmann::json::json_pointer("/" + parameter.name)] = parameter.value;
  }
  return out;
}

}  // namespace lidartwin
