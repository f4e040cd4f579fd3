// The Highway kernels of likelihood_kernels.h, compiled once per SIMD target (hwy/foreach_target.h
// includes this file again for each, which is why it stays out of the module's unity build);
// HWY_DYNAMIC_DISPATCH calls the best one the CPU runs.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "analysis/likelihood_kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

#include <hwy/highway.h>

#include "analysis/likelihood_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace lidartwin::analysis_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;
using D = hn::ScalableTag<double>;
using V = hn::Vec<D>;

// ln x = k ln 2 + ln m, m in [sqrt(1/2), sqrt(2)): with f = m - 1 and s = f / (2 + f),
// ln m = f - f^2/2 + s (f^2/2 + R(s^2)), R the minimax series of fdlibm's e_log.c (Lg1-Lg7), ln 2
// split in two so that k ln 2 is exact. x positive, normal and finite.
V Log(D d, V x) {
  const hn::RebindToUnsigned<D> du;
  const hn::RebindToSigned<D> di;
  const auto bits = hn::BitCast(du, x);
  const auto mantissa = hn::Or(hn::And(bits, hn::Set(du, 0x000FFFFFFFFFFFFFull)), hn::Set(du, 0x3FF0000000000000ull));
  V m = hn::BitCast(d, mantissa);  // [1, 2)
  V k = hn::ConvertTo(d, hn::Sub(hn::BitCast(di, hn::ShiftRight<52>(bits)), hn::Set(di, 1023)));
  const auto above = hn::Gt(m, hn::Set(d, 1.41421356237309504880));
  m = hn::IfThenElse(above, hn::Mul(m, hn::Set(d, 0.5)), m);
  k = hn::IfThenElse(above, hn::Add(k, hn::Set(d, 1.0)), k);
  const V f = hn::Sub(m, hn::Set(d, 1.0));
  const V s = hn::Div(f, hn::Add(hn::Set(d, 2.0), f));
  const V z = hn::Mul(s, s);
  const V w = hn::Mul(z, z);
  const auto term = [&](V acc, double coefficient, V power) {
    return hn::Add(hn::Set(d, coefficient), hn::Mul(power, acc));
  };
  const V t1 = hn::Mul(
      w, term(term(hn::Set(d, 1.531383769920937332e-01), 2.222219843214978396e-01, w), 3.999999999940941908e-01, w));
  const V t2 = hn::Mul(z, term(term(term(hn::Set(d, 1.479819860511658591e-01), 1.818357216161805012e-01, w),
                                    2.857142874366239149e-01, w),
                               6.666666666666735130e-01, w));
  const V r = hn::Add(t2, t1);
  const V half_f2 = hn::Mul(hn::Set(d, 0.5), hn::Mul(f, f));
  const V ln2_hi = hn::Set(d, 6.93147180369123816490e-01), ln2_lo = hn::Set(d, 1.90821492927058770002e-10);
  // k ln2_hi - ((f^2/2 - (s (f^2/2 + R) + k ln2_lo)) - f)
  const V inner = hn::Add(hn::Mul(s, hn::Add(half_f2, r)), hn::Mul(k, ln2_lo));
  return hn::Sub(hn::Mul(k, ln2_hi), hn::Sub(hn::Sub(half_f2, inner), f));
}

V NarrowBinNll(D d, V c, V h, V p_detect) {
  const V c2 = hn::Mul(c, c), h2 = hn::Mul(h, h);
  const V one = hn::Set(d, 1.0);
  // 1 + (c2 - 1) h2 / 24 + (c2 c2 - 6 c2 + 3) h2 h2 / 1920, in normal_interval's order
  const V second = hn::Div(hn::Mul(hn::Sub(c2, one), h2), hn::Set(d, 24.0));
  const V fourth_poly = hn::Add(hn::Sub(hn::Mul(c2, c2), hn::Mul(hn::Set(d, 6.0), c2)), hn::Set(d, 3.0));
  const V fourth = hn::Div(hn::Mul(hn::Mul(fourth_poly, h2), h2), hn::Set(d, 1920.0));
  const V corrected = hn::Mul(h, hn::Add(hn::Add(one, second), fourth));
  const V half_c2 = hn::Mul(hn::Set(d, 0.5), c2);
  return hn::Sub(hn::Add(half_c2, hn::Set(d, 0.91893853320467274178)), Log(d, hn::Mul(p_detect, corrected)));
}

// op over the three inputs a vector at a time; the last partial vector goes through the same code
// from a padded copy: every element's bits are the same whatever its position.
template <typename Op>
void ForEachVector(size_t n, const double* const* in, double* out, Op op) {
  const D d;
  const size_t lanes = hn::Lanes(d);
  size_t i = 0;
  for (; i + lanes <= n; i += lanes) op(d, i, in, out);
  if (i == n) return;
  constexpr size_t kMax = 64;  // doubles: beyond any target's vector
  std::array<std::array<double, kMax>, 3> padded{};
  const double* tail[3] = {padded[0].data(), padded[1].data(), padded[2].data()};
  for (size_t k = 0; k < 3; ++k) {
    padded[k].fill(1.0);
    std::copy(in[k] + i, in[k] + n, padded[k].begin());
  }
  std::array<double, kMax> result{};
  op(d, 0, tail, result.data());
  std::copy(result.begin(), result.begin() + static_cast<std::ptrdiff_t>(n - i), out + i);
}

void NarrowBinNlls(const double* c, const double* h, const double* p_detect, double* out, size_t n) {
  const double* in[3] = {c, h, p_detect};
  ForEachVector(n, in, out, [](D d, size_t i, const double* const* v, double* o) {
    hn::StoreU(NarrowBinNll(d, hn::LoadU(d, v[0] + i), hn::LoadU(d, v[1] + i), hn::LoadU(d, v[2] + i)), d, o + i);
  });
}

}  // namespace lidartwin::analysis_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lidartwin::analysis_detail {

HWY_EXPORT(NarrowBinNlls);

void narrow_bin_nlls(const double* c, const double* h, const double* p_detect, double* out, size_t n) {
  HWY_DYNAMIC_DISPATCH(NarrowBinNlls)(c, h, p_detect, out, n);
}

}  // namespace lidartwin::analysis_detail
#endif  // HWY_ONCE
