// libFuzzer: a sensor profile (--profile FILE): its beam intrinsics and its effect chain with every
// effect's parameters, parsed or refused with an InputError. Seeds: the shipped profiles.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/profile/sensor_profile.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const nlohmann::json document = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (document.is_discarded()) return 0;
  try {
    const lidartwin::SensorProfile profile = lidartwin::parse_profile(document, "fuzz input");
    if (document.is_object() && document.contains("effects")) {
      lidartwin::EffectChain::from_json(document.at("effects"), "fuzz input");
    }
  } catch (const lidartwin::InputError&) {
  }
  return 0;
}
