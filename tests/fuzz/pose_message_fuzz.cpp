// libFuzzer: the live pose UDP datagram a HIL rig sends (--pose-udp): decoded and validated, or
// refused with PoseRejected naming the field.
#include <cstddef>
#include <cstdint>
#include <span>

#include "lidartwin/pose/pose_message.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    lidartwin::decode_pose_message(std::span<const uint8_t>(data, size));
  } catch (const lidartwin::PoseRejected&) {
  }
  return 0;
}
