#pragma once
// One LidarScan message of an OSF lidar stream (a size-prefixed LidarScanMsg flatbuffer) decoded:
// its column headers and the fields lidartwin reads.
#include <cstdint>
#include <span>
#include <stdexcept>

#include "lidartwin/pcap/osf.h"

namespace lidartwin::osf_detail {

// What is wrong with the message ("field RANGE: encoded as ..."), for the reader to name the file
// and the scan.
class MessageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws MessageError for a message that does not verify, column vectors of different lengths, a
// field stored other than as an unsigned 8-, 16- or 32-bit integer, an image that does not decode
// (osf_image.h) or whose size differs from the scan's.
OsfScan decode_scan_message(std::span<const uint8_t> message, uint64_t receive_ns);

}  // namespace lidartwin::osf_detail
