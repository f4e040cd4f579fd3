// libFuzzer: a capture file as compare, fit, points and pcap-info read it (libpcap, IPv4
// reassembly, UDP): read, or refused with an InputError naming the file. The bytes go to a
// memory-backed file, as the reader takes a path. Seeds: the heads of the Ouster sample captures.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/pcap/pcap.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const int fd = memfd_create("capture.pcap", 0);
  if (ftruncate(fd, 0) != 0 || pwrite(fd, data, size, 0) != static_cast<ssize_t>(size)) return 0;
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  try {
    lidartwin::PcapStats stats;
    lidartwin::read_pcap(path, stats);
  } catch (const lidartwin::InputError&) {
  }
  return 0;
}
