// OSF field images -> values. PNG through stb_image (Debian's libstb, already the scene loader's
// library's decoder); ZPNG, a format of its own, is undone here with zstd. The layouts are those
// ouster-sdk 1.0.1 writes (ouster_osf/src/png_tools.cpp, thirdparty/zpng).
#include "pcap/osf_image.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <stb_image.h>
#include <zstd.h>

namespace lidartwin::osf_detail {
namespace {

constexpr uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
constexpr uint16_t kZpngMagic = 0xFBF8;
constexpr size_t kZpngHeaderBytes = 8;
constexpr int kMaxWidth = 65536, kMaxHeight = 4096;

uint32_t big_endian32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}
uint16_t little16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

void check_size(int width, int height, const char* format) {
  if (width <= 0 || height <= 0 || width > kMaxWidth || height > kMaxHeight) {
    throw ImageError(fmt::format("a {} of {}x{} pixels, not a lidar scan's size", format, width, height));
  }
}

// Values from pixels of `samples` samples of `bits` each, the first sample least significant.
template <typename Sample>
std::vector<uint32_t> combine(const Sample* pixels, size_t count, int samples, int bits) {
  std::vector<uint32_t> values(count);
  const auto n = static_cast<size_t>(samples);
  for (size_t i = 0; i < count; ++i) {
    uint32_t v = 0;
    for (size_t k = 0; k < n; ++k) v |= uint32_t{pixels[i * n + k]} << (bits * static_cast<int>(k));
    values[i] = v;
  }
  return values;
}

std::string stb_failure() {
  const char* reason = stbi_failure_reason();
  return std::string("a broken PNG (") + (reason ? reason : "no reason given") + ")";
}

// PNG: the IHDR chunk comes first (signature, length, "IHDR", width, height, depth, colour type).
FieldImage decode_png(std::span<const uint8_t> png) {
  if (png.size() < 33 || std::memcmp(png.data() + 12, "IHDR", 4) != 0) throw ImageError("a PNG without its IHDR");
  const int width = static_cast<int>(std::min<uint32_t>(big_endian32(png.data() + 16), INT32_MAX));
  const int height = static_cast<int>(std::min<uint32_t>(big_endian32(png.data() + 20), INT32_MAX));
  const int depth = png[24], colour = png[25];
  int samples = 0;
  if (colour == 0 && (depth == 8 || depth == 16)) samples = 1;  // grey
  if (colour == 6 && depth == 8) samples = 4;                   // RGBA; 16-bit RGBA holds 64-bit values
  if (samples == 0) {
    throw ImageError(
        fmt::format("a PNG of {}-bit colour type {}, not a layout ouster-sdk writes for 8-, 16- or "
                    "32-bit fields",
                    depth, colour));
  }
  check_size(width, height, "PNG");
  int w = 0, h = 0, channels = 0;
  const auto size = static_cast<int>(std::min<size_t>(png.size(), INT32_MAX));
  const size_t count = static_cast<size_t>(width) * static_cast<size_t>(height);
  if (depth == 16) {
    const std::unique_ptr<stbi_us, void (*)(void*)> pixels(
        stbi_load_16_from_memory(png.data(), size, &w, &h, &channels, samples), stbi_image_free);
    if (!pixels || w != width || h != height) throw ImageError(stb_failure());
    return {width, height, combine(pixels.get(), count, samples, 16), true};
  }
  const std::unique_ptr<stbi_uc, void (*)(void*)> pixels(
      stbi_load_from_memory(png.data(), size, &w, &h, &channels, samples), stbi_image_free);
  if (!pixels || w != width || h != height) throw ImageError(stb_failure());
  return {width, height, combine(pixels.get(), count, samples, 8), true};
}

// ZPNG (thirdparty/zpng in ouster-sdk): an 8-byte little-endian header (magic 0xFBF8, width,
// height as u16, channels and bytes per channel as u8), then one zstd frame of the filtered pixel
// bytes. The filter takes each byte of a pixel as the difference from the same byte of the pixel
// to its left (0 left of the first column); pixels of 3 or 4 bytes are moreover split into planes
// of W x H bytes holding, for deltas (r, g, b, a) of bytes 0-3: y = b, u = g - b, v = g - r, a.
FieldImage decode_zpng(std::span<const uint8_t> zpng) {
  if (zpng.size() < kZpngHeaderBytes) throw ImageError("a ZPNG cut short in its header");
  const int width = little16(zpng.data() + 2), height = little16(zpng.data() + 4);
  const size_t pixel_bytes = size_t{zpng[6]} * size_t{zpng[7]};
  check_size(width, height, "ZPNG");
  if (pixel_bytes != 1 && pixel_bytes != 2 && pixel_bytes != 4) {
    throw ImageError(fmt::format("a ZPNG of {}-byte pixels, not a field of 8, 16 or 32 bits", pixel_bytes));
  }
  const size_t count = static_cast<size_t>(width) * static_cast<size_t>(height);
  std::vector<uint8_t> packed(count * pixel_bytes);
  const size_t got =
      ZSTD_decompress(packed.data(), packed.size(), zpng.data() + kZpngHeaderBytes, zpng.size() - kZpngHeaderBytes);
  if (ZSTD_isError(got)) throw ImageError(std::string("a broken ZPNG (zstd: ") + ZSTD_getErrorName(got) + ")");
  if (got != packed.size()) {
    throw ImageError(
        fmt::format("a broken ZPNG ({} bytes of pixels where {}x{} need {})", got, width, height, packed.size()));
  }
  std::vector<uint8_t> bytes(packed.size());  // each pixel's bytes, least significant first
  for (size_t row = 0; row < static_cast<size_t>(height); ++row) {
    std::array<uint8_t, 4> left{};
    for (size_t c = 0; c < static_cast<size_t>(width); ++c) {
      const size_t i = row * static_cast<size_t>(width) + c;
      std::array<uint8_t, 4> delta{};
      if (pixel_bytes == 4) {
        const uint8_t y = packed[i], u = packed[count + i], v = packed[2 * count + i];
        const auto g = static_cast<uint8_t>(u + y);
        delta = {static_cast<uint8_t>(g - v), g, y, packed[3 * count + i]};
      } else {
        for (size_t k = 0; k < pixel_bytes; ++k) delta[k] = packed[i * pixel_bytes + k];
      }
      for (size_t k = 0; k < pixel_bytes; ++k) {
        left[k] = static_cast<uint8_t>(left[k] + delta[k]);
        bytes[i * pixel_bytes + k] = left[k];
      }
    }
  }
  return {width, height, combine(bytes.data(), count, static_cast<int>(pixel_bytes), 8), false};
}

}  // namespace

FieldImage decode_field_image(std::span<const uint8_t> encoded) {
  if (encoded.size() >= 8 && std::equal(kPngSignature, kPngSignature + 8, encoded.begin())) return decode_png(encoded);
  if (encoded.size() >= 2 && little16(encoded.data()) == kZpngMagic) return decode_zpng(encoded);
  throw ImageError("encoded neither as PNG nor as ZPNG: an encoding lidartwin does not know");
}

}  // namespace lidartwin::osf_detail
