#pragma once
// One LidarScan field as an OSF file stores it: an image, H rows by W columns, encoded as a PNG or
// (ouster-cli's default in ouster-sdk 1.0.1) as a ZPNG.
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

namespace lidartwin::osf_detail {

// Why an image did not decode, for the reader to name the file, the scan and the field.
class ImageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct FieldImage {
  int width = 0;
  int height = 0;
  std::vector<uint32_t> values;  // row-major: element r * width + c
  // The SDK destaggers a field before encoding it as PNG, and encodes it as it is for ZPNG
  // (ouster-sdk 1.0.1: ouster_osf/src/png_tools.cpp staggers PNG fields back on reading and leaves
  // ZPNG ones; zpng_lidarframe_encoder.cpp ignores the pixel shifts).
  bool destaggered = false;
};

// The image's pixels. PNG, as png_tools.cpp writes fields: 8-bit ones as 8-bit grey, 16-bit ones as
// 16-bit grey, 32-bit ones as 8-bit RGBA with the value's least significant byte in red. ZPNG:
// see osf_image.cpp. Throws ImageError for another encoding, a layout the SDK does not write for
// fields of up to 32 bits, or a broken image.
FieldImage decode_field_image(std::span<const uint8_t> encoded);

}  // namespace lidartwin::osf_detail
