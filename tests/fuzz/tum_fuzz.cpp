// libFuzzer: a TUM trajectory file (--trajectory): loaded, or refused with an InputError naming the
// line. Seeds: the shipped trajectories.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/pose/pose.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const int fd = memfd_create("trajectory.tum", 0);
  if (ftruncate(fd, 0) != 0 || pwrite(fd, data, size, 0) != static_cast<ssize_t>(size)) return 0;
  try {
    const lidartwin::Trajectory trajectory =
        lidartwin::Trajectory::load_tum("/proc/self/fd/" + std::to_string(fd), /*loop=*/false);
    (void)trajectory;
  } catch (const lidartwin::InputError&) {
  }
  return 0;
}
