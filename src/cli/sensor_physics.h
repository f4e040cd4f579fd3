#pragma once
// The physics a command gives the forward model: the profile's effect chain and IMU errors, or,
// with --ideal, none of the noise. `record` and `serve` both take --ideal through here, so the
// flag means the same to both and a served stream matches a recorded one.
#include <CLI/CLI.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin::cli {

struct SensorPhysics {
  EffectChain chain;
  ImuNoise imu;
};

// ideal: no noise or dropout. Radiometry (deterministic expected values) keeps signal,
// reflectivity and NIR meaningful; the profile's range window and the wire's range step remain;
// the IMU is exact.
SensorPhysics sensor_physics(const SensorProfile& profile, bool ideal);

// --ideal on a subcommand, with the one help text.
void add_ideal_flag(CLI::App& command, bool& ideal);

}  // namespace lidartwin::cli
