// Highway kernels of lane_kernels.h, compiled once per SIMD target (hwy/foreach_target.h includes
// this file again for each); HWY_DYNAMIC_DISPATCH calls the best one the CPU runs. Maxima are
// comparisons and selects as std::max writes them, so ties and signed zeros resolve alike.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "caster/lane_kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <cmath>

#include <hwy/highway.h>

#include "caster/lane_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace lidartwin::caster_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// At most 16 lanes a vector, so a packet's 16 lanes are whole vectors on every target.
using LaneTag = hn::CappedTag<float, kLanes>;

void TransformLanes(const LaneRays& in, const float (*rotation)[kLanes], const float (*translation)[kLanes],
                    const LaneRaysOut& out) {
  const LaneTag df;
  const auto zero = hn::Zero(df);
  for (size_t i = 0; i < kLanes; i += hn::Lanes(df)) {
    const auto row = [&](const float* const* x, size_t j, decltype(zero) d) {
      const auto ax = hn::Mul(hn::LoadU(df, rotation[3 * j] + i), hn::LoadU(df, x[0] + i));
      const auto by = hn::Mul(hn::LoadU(df, rotation[3 * j + 1] + i), hn::LoadU(df, x[1] + i));
      const auto cz = hn::Mul(hn::LoadU(df, rotation[3 * j + 2] + i), hn::LoadU(df, x[2] + i));
      return hn::Add(hn::Add(hn::Add(ax, by), cz), d);
    };
    for (size_t j = 0; j < 3; ++j) {
      hn::StoreU(row(in.org, j, hn::LoadU(df, translation[j] + i)), df, out.org[j] + i);
      hn::StoreU(row(in.dir, j, zero), df, out.dir[j] + i);
    }
  }
}

void CosIncidenceLanes(const float* nx, const float* ny, const float* nz, const float* dx, const float* dy,
                       const float* dz, float* out) {
  const LaneTag df;
  const auto one = hn::Set(df, 1.0f);
  for (size_t i = 0; i < kLanes; i += hn::Lanes(df)) {
    const auto x = hn::LoadU(df, nx + i), y = hn::LoadU(df, ny + i), z = hn::LoadU(df, nz + i);
    const auto dot = hn::Add(hn::Add(hn::Mul(x, hn::LoadU(df, dx + i)), hn::Mul(y, hn::LoadU(df, dy + i))),
                             hn::Mul(z, hn::LoadU(df, dz + i)));
    const auto norm = hn::Sqrt(hn::Add(hn::Add(hn::Mul(x, x), hn::Mul(y, y)), hn::Mul(z, z)));
    const auto c = hn::Div(hn::Abs(dot), norm);
    hn::StoreU(hn::IfThenElse(hn::Lt(c, one), c, one), df, out + i);
  }
}

float DepthStepScalar(float a, float b) {
  const bool hit_a = a > 0.0f, hit_b = b > 0.0f;
  const float farther = a < b ? b : a;
  const float threshold = 0.3f < 0.05f * farther ? 0.05f * farther : 0.3f;
  return (hit_a != hit_b) || (hit_a && hit_b && std::abs(a - b) > threshold) ? 1.0f : 0.0f;
}

// The depth-step rule of DepthStepScalar and choose_edge_partner, for returns a and b that both
// hit: apart by more than 0.3 m or 5 % of the farther.
template <class D, class V>
HWY_INLINE auto HitsApart(D df, V a, V b) {
  const auto scaled = hn::Mul(hn::Set(df, 0.05f), hn::IfThenElse(hn::Lt(a, b), b, a));
  const auto near = hn::Set(df, 0.3f);
  return hn::Gt(hn::Abs(hn::Sub(a, b)), hn::IfThenElse(hn::Lt(near, scaled), scaled, near));
}

void DepthSteps(const float* range, size_t rows, uint8_t* step) {
  const hn::ScalableTag<float> df;
  const hn::Rebind<int32_t, decltype(df)> di;
  const hn::Rebind<uint8_t, decltype(df)> du8;
  const size_t lanes = hn::Lanes(df);
  const auto zero = hn::Zero(df);
  size_t r = 0;
  for (; rows > 0 && r + lanes <= rows - 1; r += lanes) {
    const auto a = hn::LoadU(df, range + r), b = hn::LoadU(df, range + r + 1);
    const auto hit_a = hn::Gt(a, zero), hit_b = hn::Gt(b, zero);
    const auto edge = hn::Or(hn::Xor(hit_a, hit_b), hn::And(hn::And(hit_a, hit_b), HitsApart(df, a, b)));
    const auto ones = hn::IfThenElseZero(hn::RebindMask(di, edge), hn::Set(di, 1));
    hn::StoreU(hn::DemoteTo(du8, ones), du8, step + r);
  }
  for (; r + 1 < rows; ++r) step[r] = static_cast<uint8_t>(DepthStepScalar(range[r], range[r + 1]));
}

// choose_edge_partner with a select per candidate in place of its branches: the same comparisons
// on the same IEEE products, quotient and root, so the same partner on every target.
void EdgePartners(const float* range, const float* cos_incidence, const PartnerCandidates& candidates,
                  const PartnerChoice& out) {
  const hn::ScalableTag<float> df;
  const auto zero = hn::Zero(df), two = hn::Set(df, 2.0f), one = hn::Set(df, 1.0f);
  const auto least_cos = hn::Set(df, 0.05f);
  for (size_t r = 0; r < kPartnerRows; r += hn::Lanes(df)) {
    const auto a = hn::LoadU(df, range + r);
    const auto hit = hn::Gt(a, zero);
    auto c = hn::LoadU(df, cos_incidence + r);  // std::clamp(c, 0.05, 1)
    c = hn::IfThenElse(hn::Lt(c, least_cos), least_cos, hn::IfThenElse(hn::Lt(one, c), one, c));
    const auto slope = hn::Div(hn::Mul(a, hn::Sqrt(hn::Sub(one, hn::Mul(c, c)))), c);
    const auto twice_slope = hn::Mul(two, slope);
    auto largest = zero, partner = zero, reflectance = zero, spacing = zero;
    for (size_t k = 0; k < 4; ++k) {
      const auto b = hn::LoadU(df, candidates.range[k] + r);
      const auto gap = hn::LoadU(df, candidates.spacing[k] + r);
      const auto step = hn::Abs(hn::Sub(b, a));
      const auto take = hn::And(
          hn::And(hit, hn::Gt(b, zero)),
          hn::And(HitsApart(df, a, b), hn::And(hn::Gt(step, hn::Mul(twice_slope, gap)), hn::Gt(step, largest))));
      largest = hn::IfThenElse(take, step, largest);
      partner = hn::IfThenElse(take, b, partner);
      reflectance = hn::IfThenElse(take, hn::LoadU(df, candidates.reflectance[k] + r), reflectance);
      spacing = hn::IfThenElse(take, gap, spacing);
    }
    hn::StoreU(partner, df, out.range + r);
    hn::StoreU(reflectance, df, out.reflectance + r);
    hn::StoreU(spacing, df, out.spacing + r);
  }
}

}  // namespace lidartwin::caster_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lidartwin::caster_detail {

HWY_EXPORT(TransformLanes);
HWY_EXPORT(CosIncidenceLanes);
HWY_EXPORT(DepthSteps);
HWY_EXPORT(EdgePartners);

void transform_lanes(const LaneRays& in, const float (*rotation)[kLanes], const float (*translation)[kLanes],
                     const LaneRaysOut& out) {
  HWY_DYNAMIC_DISPATCH(TransformLanes)(in, rotation, translation, out);
}

void cos_incidence_lanes(const float* nx, const float* ny, const float* nz, const float* dx, const float* dy,
                         const float* dz, float* out) {
  HWY_DYNAMIC_DISPATCH(CosIncidenceLanes)(nx, ny, nz, dx, dy, dz, out);
}

void depth_steps(const float* range, size_t rows, uint8_t* step) {
  HWY_DYNAMIC_DISPATCH(DepthSteps)(range, rows, step);
}

void edge_partners(const float* range, const float* cos_incidence, const PartnerCandidates& candidates,
                   const PartnerChoice& out) {
  HWY_DYNAMIC_DISPATCH(EdgePartners)(range, cos_incidence, candidates, out);
}

}  // namespace lidartwin::caster_detail
#endif  // HWY_ONCE
