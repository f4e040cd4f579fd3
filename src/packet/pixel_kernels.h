#pragma once
// Assembling one column's pixels from its channels (packet_encode.cpp), as a SIMD kernel chosen at
// run time for the CPU (Google Highway: SSSE3, SSE4, AVX2, AVX-512, NEON...), one call a column.
// Integer shifts, masks and moves only: every target writes the same bytes.
#include <cstddef>
#include <cstdint>

namespace lidartwin::packet_detail {

inline constexpr size_t kMaxPixelWords = 6;  // the widest pixel, 24 bytes
inline constexpr size_t kMaxPixelRows = 128;

// A channel's place in the pixel: the 32-bit word that holds it, and value >> down << up, & mask =
// the field's bits in that word.
struct WordLane {
  size_t word = 0;
  int down = 0;
  int up = 0;
  uint32_t mask = 0;
};

// One column's pixels from its channels, in two passes over planes (one per 32-bit word of the
// pixel): each channel ORed into its plane, then the planes interleaved into pixels
// (pixels[row * words + w]); words in [1, kMaxPixelWords], rows at most kMaxPixelRows.
void assemble_pixels(const uint32_t* const* values, const WordLane* lanes, size_t channels, size_t words, size_t rows,
                     uint32_t* pixels);

}  // namespace lidartwin::packet_detail
