#pragma once
// The two passes that assemble one column's pixels from its channels (packet_encode.cpp), as
// SIMD kernels chosen at run time for the CPU (Google Highway: SSSE3, SSE4, AVX2, AVX-512, NEON...).
// Integer shifts, masks and moves only: every target writes the same bytes.
#include <cstddef>
#include <cstdint>

namespace lidartwin::packet_detail {

inline constexpr size_t kMaxPixelWords = 6;  // the widest pixel, 24 bytes

// plane[row] |= ((values[row] >> down) << up) & mask for rows [0, rows): one channel into the
// 32-bit word of the pixel that holds it.
void or_into_plane(const uint32_t* values, size_t rows, int down, int up, uint32_t mask, uint32_t* plane);
// pixels[row * words + w] = planes[w][row]: the planes (one per 32-bit word) interleaved into
// pixels, words in [1, kMaxPixelWords].
void interleave_planes(const uint32_t* const* planes, size_t words, size_t rows, uint32_t* pixels);

}  // namespace lidartwin::packet_detail
