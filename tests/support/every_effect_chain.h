#pragma once
// Every library effect on at once, with values that make each one act: what pipeline_bench prices
// and what the determinism test records. `range_noise` is the chain's sigma(r) effect.
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace lidartwin::test {

// A profile chain's sigma(r) effect (range_noise_piecewise or range_noise_linear), by name: its
// place moves as effects are added before it (effects[1] was mixed_pixels once E6 came second).
inline nlohmann::json range_noise_of(const nlohmann::json& effects) {
  for (const auto& effect : effects) {
    if (effect.at("name").get<std::string>().starts_with("range_noise")) return effect;
  }
  throw std::invalid_argument("the profile's chain has no range_noise effect");
}

inline nlohmann::json every_effect_chain(const nlohmann::json& range_noise) {
  return nlohmann::json::array({
      {{"name", "radiometry"}},
      {{"name", "mixed_pixels"}},
      {{"name", "signal_precision"}, {"k_m", 0.05}},
      {{"name", "signal_outliers"}, {"probability", 0.05}},
      {{"name", "range_walk"}, {"walk_m", 0.005}},
      {{"name", "incidence"}},
      {{"name", "beam_calibration"}, {"offset_sigma_m", 0.01}},
      {{"name", "drift"}, {"warmup_offset_m", 0.02}},
      {{"name", "vibration"}, {"angular_rms_deg", 0.02}, {"translation_rms_m", 0.002}},
      range_noise,
      {{"name", "window"}, {"near_return_probability", 0.05}, {"near_return_range_m", 0.4}},
      {{"name", "fog"}, {"attenuation_per_m", 0.01}, {"soft_return_probability", 0.02}},
      {{"name", "halo"}, {"dropout_probability", 0.1}},
      {{"name", "dropout"}, {"threshold_photons", 2.0}},
      {{"name", "false_alarms"}, {"probability_at_reference", 0.01}, {"reference_near_ir_photons", 10.0}},
      {{"name", "shot_noise"}},
      {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}},
      {{"name", "range_quantization"}},
  });
}

}  // namespace lidartwin::test
