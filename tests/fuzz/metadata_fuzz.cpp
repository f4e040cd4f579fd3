// libFuzzer: a sensor's metadata JSON (GET sensor/metadata, a capture's metadata file) as lidartwin
// reads it: parsed, or refused with an InputError; nothing else escapes. Seeds: the Ouster sample
// metadata (tools/fuzz).
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "lidartwin/error.h"
#include "lidartwin/metadata/metadata.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const nlohmann::json document = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (document.is_discarded()) return 0;
  try {
    lidartwin::parse_metadata(document, "fuzz input");
  } catch (const lidartwin::InputError&) {
  }
  return 0;
}
