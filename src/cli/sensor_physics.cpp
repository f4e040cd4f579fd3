#include "cli/sensor_physics.h"

#include "cli/unit_twin.h"

namespace lidartwin::cli {

namespace {
EffectChain ideal_chain(const SensorProfile& profile) {
  nlohmann::json chain = nlohmann::json::array();
  for (const auto& effect : profile.effects) {
    if (effect.value("name", "") == "radiometry") chain.push_back(effect);
  }
  chain.push_back({{"name", "range_limits"}, {"min_m", profile.min_range_m}, {"max_m", profile.max_range_m}});
  chain.push_back({{"name", "range_quantization"}});
  return EffectChain::from_json(chain, "--ideal chain for profile " + profile.name);
}
}  // namespace

SensorPhysics sensor_physics(const SensorProfile& profile, bool ideal) {
  if (ideal) return {ideal_chain(profile), ImuNoise{}};
  return {profile_chain(profile), profile.imu};
}

void add_ideal_flag(CLI::App& command, bool& ideal) {
  command.add_flag(
      "--ideal", ideal,
      "no noise or dropout: ideal ranges on the wire's step, within the profile's range, and an exact IMU");
}

}  // namespace lidartwin::cli
