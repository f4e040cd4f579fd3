// libFuzzer: IMU packets, LEGACY and the NMEA-bearing profile in both header layouts. Byte 0 gives
// the measurements per packet (0-3) of the NMEA form.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "lidartwin/packet/imu_packet.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace lidartwin;
  if (size == 0) return 0;
  const std::span<const uint8_t> bytes(data + 1, size - 1);
  if (decode_legacy_imu(bytes).has_value() != (bytes.size() == kLegacyImuPacketSize)) __builtin_trap();
  const int measurements = data[0] % 4;
  for (const HeaderType type : {HeaderType::kStandard, HeaderType::kFusa}) {
    std::string error;
    if (!decode_nmea_imu(bytes, measurements, type, &error) && error.empty()) __builtin_trap();
  }
  return 0;
}
