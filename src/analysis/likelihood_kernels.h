#pragma once
// The diagnosis' fits spend most of their time scoring returns in one common case (pixel_likelihood:
// no outliers, no partner, the window holding the Gaussian, a bin narrow against sigma). Its
// arithmetic, vectorised with Google Highway and chosen at run time for the CPU, in multiplies,
// adds and a division alone (the build does not fuse them), so that every SIMD target gives the
// same bits.
#include <cstddef>

namespace lidartwin::analysis_detail {

// out[i] = c^2 / 2 + ln sqrt(2 pi) - ln(p_detect h (1 + (c^2 - 1) h^2 / 24 + (c^4 - 6 c^2 + 3) h^4 / 1920))
// for i < n: the NLL of a return c sigmas from the mean, in a bin h sigmas wide (the midpoint rule
// with its corrections), detected with probability p_detect. The logarithm is the kernel's own
// (fdlibm's series; within an ulp or two of libm's). Needs p_detect h a normal positive number.
void narrow_bin_nlls(const double* c, const double* h, const double* p_detect, double* out, size_t n);

}  // namespace lidartwin::analysis_detail
