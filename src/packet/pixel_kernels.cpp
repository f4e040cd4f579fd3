// Highway kernels of pixel_kernels.h, compiled once per SIMD target (hwy/foreach_target.h includes
// this file again for each); HWY_DYNAMIC_DISPATCH calls the best one the CPU runs. The scalar
// tails do what the vectors do, for heights that are not a multiple of a vector.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "packet/pixel_kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <algorithm>

#include <hwy/highway.h>

#include "packet/pixel_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace lidartwin::packet_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void OrIntoPlane(const uint32_t* values, size_t rows, int down, int up, uint32_t mask, uint32_t* plane) {
  const hn::ScalableTag<uint32_t> d;
  const size_t lanes = hn::Lanes(d);
  const auto field_mask = hn::Set(d, mask);
  size_t row = 0;
  for (; row + lanes <= rows; row += lanes) {
    const auto field = hn::ShiftLeftSame(hn::ShiftRightSame(hn::LoadU(d, values + row), down), up);
    hn::StoreU(hn::Or(hn::LoadU(d, plane + row), hn::And(field, field_mask)), d, plane + row);
  }
  for (; row < rows; ++row) plane[row] |= ((values[row] >> down) << up) & mask;
}

// Words 2, 3 and 4 (the common pixel sizes: 8, 12 and 16 bytes) through Highway's interleaving
// stores; the others one word at a time.
void InterleavePlanes(const uint32_t* const* planes, size_t words, size_t rows, uint32_t* pixels) {
  const hn::ScalableTag<uint32_t> d;
  const size_t lanes = hn::Lanes(d);
  size_t row = 0;
  const auto plane = [&](size_t w) { return hn::LoadU(d, planes[w] + row); };
  if (words == 2) {
    for (; row + lanes <= rows; row += lanes) hn::StoreInterleaved2(plane(0), plane(1), d, pixels + row * 2);
  } else if (words == 3) {
    for (; row + lanes <= rows; row += lanes) hn::StoreInterleaved3(plane(0), plane(1), plane(2), d, pixels + row * 3);
  } else if (words == 4) {
    for (; row + lanes <= rows; row += lanes) {
      hn::StoreInterleaved4(plane(0), plane(1), plane(2), plane(3), d, pixels + row * 4);
    }
  }
  for (; row < rows; ++row) {
    for (size_t w = 0; w < words; ++w) pixels[row * words + w] = planes[w][row];
  }
}

void AssemblePixels(const uint32_t* const* values, const WordLane* lanes, size_t channels, size_t words, size_t rows,
                    uint32_t* pixels) {
  HWY_ALIGN uint32_t planes[kMaxPixelWords][kMaxPixelRows];
  for (size_t w = 0; w < words; ++w) std::fill_n(planes[w], rows, 0u);
  for (size_t k = 0; k < channels; ++k) {
    OrIntoPlane(values[k], rows, lanes[k].down, lanes[k].up, lanes[k].mask, planes[lanes[k].word]);
  }
  const uint32_t* plane_rows[kMaxPixelWords];
  for (size_t w = 0; w < words; ++w) plane_rows[w] = planes[w];
  InterleavePlanes(plane_rows, words, rows, pixels);
}

}  // namespace lidartwin::packet_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lidartwin::packet_detail {

HWY_EXPORT(AssemblePixels);

void assemble_pixels(const uint32_t* const* values, const WordLane* lanes, size_t channels, size_t words, size_t rows,
                     uint32_t* pixels) {
  HWY_DYNAMIC_DISPATCH(AssemblePixels)(values, lanes, channels, words, rows, pixels);
}

}  // namespace lidartwin::packet_detail
#endif  // HWY_ONCE
