// libFuzzer: an OSF recording (ouster-cli's) as compare and pcap-info read it: its chunks,
// FlatBuffers, and PNG or ZPNG fields, read or refused with an InputError. Seeds: the heads of the
// OSF samples.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/pcap/osf.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const int fd = memfd_create("recording.osf", 0);
  if (ftruncate(fd, 0) != 0 || pwrite(fd, data, size, 0) != static_cast<ssize_t>(size)) return 0;
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  try {
    lidartwin::OsfReader reader(path);
    while (reader.next()) {
    }
  } catch (const lidartwin::InputError&) {
  }
  return 0;
}
