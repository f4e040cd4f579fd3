#pragma once
// The factories and cards of the effects built into lidartwin, one each per src/effects/<effect>.cpp. The
// registry lists them explicitly: self-registration from static initializers is dropped by the
// linker when nothing else references the object file of a static library.
#include <memory>
#include <string_view>

#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect.h"
#include "lidartwin/effects/effect_card.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin::effects_detail {

using json_reader::Location;

std::unique_ptr<Effect> make_radiometry(const nlohmann::json& params, const Location& at);
std::unique_ptr<Effect> make_range_noise_linear(const nlohmann::json& params, const Location& at);
std::unique_ptr<Effect> make_range_noise_piecewise(const nlohmann::json& params, const Location& at);
std::unique_ptr<Effect> make_range_limits(const nlohmann::json& params, const Location& at);
std::unique_ptr<Effect> make_range_quantization(const nlohmann::json& params, const Location& at);
std::unique_ptr<Effect> make_dropout(const nlohmann::json& params, const Location& at);
std::unique_ptr<Effect> make_signal_precision(const nlohmann::json& params, const Location& at);  // E2
std::unique_ptr<Effect> make_signal_outliers(const nlohmann::json& params, const Location& at);   // E2's tails
std::unique_ptr<Effect> make_range_walk(const nlohmann::json& params, const Location& at);        // E3
std::unique_ptr<Effect> make_incidence(const nlohmann::json& params, const Location& at);         // E4
std::unique_ptr<Effect> make_mixed_pixels(const nlohmann::json& params, const Location& at);      // E6
std::unique_ptr<Effect> make_halo(const nlohmann::json& params, const Location& at);              // E8
std::unique_ptr<Effect> make_beam_calibration(const nlohmann::json& params, const Location& at);  // E10
std::unique_ptr<Effect> make_vibration(const nlohmann::json& params, const Location& at);         // E11
std::unique_ptr<Effect> make_drift(const nlohmann::json& params, const Location& at);             // E12
std::unique_ptr<Effect> make_fog(const nlohmann::json& params, const Location& at);               // E13
std::unique_ptr<Effect> make_false_alarms(const nlohmann::json& params, const Location& at);      // E14
std::unique_ptr<Effect> make_shot_noise(const nlohmann::json& params, const Location& at);        // section 2.2
std::unique_ptr<Effect> make_window(const nlohmann::json& params, const Location& at);            // E16

EffectCard radiometry_card();
EffectCard range_noise_linear_card();
EffectCard range_noise_piecewise_card();
EffectCard signal_precision_card();
EffectCard signal_outliers_card();
EffectCard range_walk_card();
EffectCard incidence_card();
EffectCard drift_card();
EffectCard dropout_card();
EffectCard mixed_pixels_card();
EffectCard halo_card();
EffectCard range_quantization_card();
EffectCard beam_calibration_card();
EffectCard vibration_card();
EffectCard fog_card();
EffectCard false_alarms_card();
EffectCard shot_noise_card();
EffectCard range_limits_card();
EffectCard window_card();

}  // namespace lidartwin::effects_detail
