// Per-pixel likelihood of a measurement under the chain's prediction (lidar-physics.md 3.5).
#include "lidartwin/analysis/pixel_likelihood.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <numbers>
#include <optional>
#include <vector>

#include "analysis/likelihood_kernels.h"

namespace lidartwin {
namespace {

constexpr double kSqrtHalf = 0.70710678118654752440;
constexpr double kWholeZ = 8.5;   // Phi(-8.5) = 9.5e-18: below half an ulp of 1
constexpr double kNarrowZ = 0.1;  // interval width, in sigmas, up to which the midpoint rule is used

// The probability mass of the window under the Gaussian centred at mean (with sigma_m, or sigma).
double window_mass(const RangeModel& m, double mean, double sigma) {
  return normal_interval((m.window_min_m - mean) / sigma, (m.window_max_m - mean) / sigma);
}
double window_mass(const RangeModel& m, double mean) { return window_mass(m, mean, m.sigma_m); }

// The probability of [lo, hi] under the Gaussian part truncated to the window: the pixel's own
// surface and, with weight partner_mix, its edge partner's (E6) or a halo's (E8), a tail_mix share
// of the pixel's own returns wider (E2's tails), the mixture renormalized by the mass it has inside
// the window (a partner inside it may be all that is detected).
double gaussian_interval(const RangeModel& m, double lo, double hi, double gaussian_mass) {
  const auto interval = [&](double mean, double sigma) {
    return normal_interval((lo - mean) / sigma, (hi - mean) / sigma);
  };
  if (m.partner_mix <= 0.0 && m.tail_mix <= 0.0) {
    return gaussian_mass > 0.0 ? interval(m.mean_m, m.sigma_m) / gaussian_mass : 0.0;
  }
  const double own = 1.0 - m.partner_mix, tail = own * m.tail_mix, core = own - tail;
  double mass = core * gaussian_mass, p = core * interval(m.mean_m, m.sigma_m);
  if (m.partner_mix > 0.0) {
    const double partner_mean = m.mean_m + m.partner_offset_m, partner_sigma = m.partner_sigma();
    mass += m.partner_mix * window_mass(m, partner_mean, partner_sigma);
    p += m.partner_mix * interval(partner_mean, partner_sigma);
  }
  if (tail > 0.0) {
    mass += tail * window_mass(m, m.mean_m, m.tail_sigma_m);
    p += tail * interval(m.mean_m, m.tail_sigma_m);
  }
  return mass > 0.0 ? p / mass : 0.0;
}

// The CDF of the returned range (before quantization): the truncated Gaussian part mixed with the
// uniform outlier component, both on the window.
double range_cdf(const RangeModel& m, double x, double gaussian_mass) {
  const double width = m.window_max_m - m.window_min_m;
  const double clipped = std::clamp(x, m.window_min_m, m.window_max_m);
  const double gaussian = gaussian_interval(m, m.window_min_m, clipped, gaussian_mass);
  const double uniform = width > 0.0 ? (clipped - m.window_min_m) / width : 0.0;
  return std::clamp((1.0 - m.outlier_mix) * gaussian + m.outlier_mix * uniform, 0.0, 1.0);
}

// The midpoint rule's Taylor corrections for a narrow interval of width h (in sigmas) centred at c:
// its probability is phi(c) h times this.
double midpoint_correction(double c, double h) {
  const double c2 = c * c, h2 = h * h;
  return 1.0 + (c2 - 1.0) * h2 / 24.0 + (c2 * c2 - 6.0 * c2 + 3.0) * h2 * h2 / 1920.0;
}

double normal_pdf(double x) {
  return std::isfinite(x) ? std::exp(-0.5 * x * x) / std::sqrt(2.0 * std::numbers::pi) : 0.0;
}

// Mean and sd of a standard normal truncated to [a, b] (mass = its probability there).
struct TruncatedMoments {
  double mean = 0.0;
  double sd = 1.0;
};
TruncatedMoments truncated_moments(double a, double b, double mass) {
  if (a < -8.0 && b > 8.0) return {};  // the window holds all of it
  if (mass <= 1e-300) return {};
  const double pa = normal_pdf(a), pb = normal_pdf(b);
  const double ta = std::isfinite(a) ? a * pa : 0.0, tb = std::isfinite(b) ? b * pb : 0.0;
  const double mean = (pa - pb) / mass;
  const double variance = 1.0 + (ta - tb) / mass - mean * mean;
  return {mean, std::sqrt(std::max(variance, 1e-12))};
}

// The partner's component lies within this many sigmas of the pixel's own: the two overlap, and
// the expected NLL is the mixture's entropy, by quadrature (kOverlapPoints midpoints over both).
constexpr double kOverlapSigmas = 10.0;
constexpr int kOverlapPoints = 400;

bool partner_overlaps(const RangeModel& m) {
  return m.partner_mix > 0.0 && std::abs(m.partner_offset_m) < kOverlapSigmas * std::max(m.sigma_m, m.partner_sigma());
}

// E[-ln f] and Var[-ln f] of the Gaussian mixture (own and partner) truncated to the window, f its
// density: the entropy of narrow bins is this less ln(step).
struct MixtureEntropy {
  double mean = 0.0;
  double variance = 0.0;
};
MixtureEntropy mixture_entropy(const RangeModel& m) {
  const double pe = std::clamp(m.partner_mix, 0.0, 1.0);
  const double mean2 = m.mean_m + m.partner_offset_m, sigma2 = m.partner_sigma();
  const double lo = std::max(m.window_min_m, std::min(m.mean_m - 9.0 * m.sigma_m, mean2 - 9.0 * sigma2));
  const double hi = std::min(m.window_max_m, std::max(m.mean_m + 9.0 * m.sigma_m, mean2 + 9.0 * sigma2));
  if (hi <= lo) return {};
  const double mass = (1.0 - pe) * window_mass(m, m.mean_m) + pe * window_mass(m, mean2, sigma2);
  if (mass <= 0.0) return {};
  const double dx = (hi - lo) / kOverlapPoints;
  double h = 0.0, h2 = 0.0;
  for (int k = 0; k < kOverlapPoints; ++k) {
    const double x = lo + (k + 0.5) * dx;
    const double f = ((1.0 - pe) * normal_pdf((x - m.mean_m) / m.sigma_m) / m.sigma_m +
                      pe * normal_pdf((x - mean2) / sigma2) / sigma2) /
                     mass;
    if (f <= 0.0) continue;
    const double nll = -std::log(f);
    h += f * nll * dx;
    h2 += f * nll * nll * dx;
  }
  return {h, std::max(h2 - h * h, 0.0)};
}

// E[-ln P(bin)] and its variance for the whole mixture of Gaussians (the pixel's own, its tail's,
// a partner's) truncated to the window and quantized: where the tail is, the components overlap by
// construction. Bins narrow against the narrowest component: the density by the midpoint rule, on a
// grid a quarter of that sigma apart; wider bins: bin by bin. At most kMixturePoints either way
// (the grid coarsens beyond that).
constexpr double kMixturePoints = 20000.0;

// E[-ln q] and Var[-ln q] over the bins q of width h (in sigmas) of g = w1 N(0, 1) + w2 N(0, k^2),
// k >= 1, all in the narrower component's sigmas, less ln h: what a pixel's own core and E2's tail
// give where the window holds both and bins are narrow against the narrower. With L = -ln g, a bin's
// probability is h g (1 + h^2 g'' / 24 g) to h^4, so the mean is E[L] + h^2 J / 24, J = E[L''] (g's
// Fisher information), and the variance Var[L] + h^2 Cov(L, L'') / 12 (for a lone Gaussian h^2 / 24
// and nothing). g is even: twice the integrals over u >= 0, in two parts:
// - up to U, where the narrower's density falls below e^-36 of the wider's, Gauss-Legendre on
//   panels 1.5 sigmas wide, 8 nodes each (L is smooth at that scale, its bend where the components
//   cross included);
// - beyond U, g is the wider alone to rounding: L = A + v^2 / 2 with v = u / k, L'' = 1 / k^2, and
//   the integrals are the normal's upper tail moments Q(s), M2(s) = s phi(s) + Q(s), M4 = s^3 phi(s) + 3 M2.
// Against the bins summed one by one: within 3e-7 for h up to 0.1, 1.2e-5 at 0.25, for w2 from 1e-6
// to 0.9 and k from 1 to 60; some 50 nodes where a grid a quarter sigma apart takes 72 k.
MixtureEntropy two_gaussian_entropy(double w1, double w2, double k, double h) {
  constexpr std::array<double, 4> kNodes = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267,
                                            0.9602898564975363};
  constexpr std::array<double, 4> kWeights = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745,
                                              0.1012285362903763};
  constexpr double kPanel = 1.5, kNegligible = 36.0;
  const double ln_sqrt_2pi = 0.5 * std::log(2.0 * std::numbers::pi);
  const double ln_a = std::log(w1), ln_b = std::log(w2 / k), inv_k2 = 1.0 / (k * k);
  const double gap = ln_a - ln_b + kNegligible;  // ln(w1 k / w2) + 36: where the narrower still counts
  const double shrink = 1.0 - inv_k2;
  const double cut = gap <= 0.0 ? 0.0 : shrink > 0.0 ? std::sqrt(2.0 * gap / shrink) : HUGE_VAL;
  const double top = std::min(cut, 9.0 * k);
  const int panels = static_cast<int>(std::ceil(top / kPanel));
  double mean = 0.0, square = 0.0, fisher = 0.0, cross = 0.0;  // E[L], E[L^2], E[L''], E[L L'']
  const auto add = [&](double u, double weight) {
    const double a = ln_a - 0.5 * u * u, b = ln_b - 0.5 * inv_k2 * u * u, top_log = std::max(a, b);
    const double ra = std::exp(a - top_log), rb = std::exp(b - top_log), sum = ra + rb;
    const double nll = ln_sqrt_2pi - top_log - std::log(sum);
    const double slope = -(ra + rb * inv_k2) * u / sum;                                     // g' / g
    const double bend = (ra * (u * u - 1.0) + rb * inv_k2 * (u * u * inv_k2 - 1.0)) / sum;  // g'' / g
    const double curvature = slope * slope - bend;                                          // L''
    const double mass = 2.0 * weight * std::exp(-nll);
    mean += mass * nll;
    square += mass * nll * nll;
    fisher += mass * curvature;
    cross += mass * nll * curvature;
  };
  for (int p = 0; p < panels; ++p) {
    const double half = 0.5 * top / panels, centre = (2 * p + 1) * half;
    for (size_t j = 0; j < kNodes.size(); ++j) {
      add(centre - half * kNodes[j], half * kWeights[j]);
      add(centre + half * kNodes[j], half * kWeights[j]);
    }
  }
  if (cut < 9.0 * k) {
    const double s = cut / k, phi = normal_pdf(s), q = 0.5 * std::erfc(s * kSqrtHalf);
    const double m2 = s * phi + q, m4 = s * s * s * phi + 3.0 * m2, a = ln_sqrt_2pi - ln_b;
    const double beyond = 2.0 * w2 * (a * q + 0.5 * m2);
    mean += beyond;
    square += 2.0 * w2 * (a * a * q + a * m2 + 0.25 * m4);
    fisher += 2.0 * w2 * q * inv_k2;
    cross += beyond * inv_k2;
  }
  const double h2 = h * h;
  return {mean + h2 * fisher / 24.0, std::max(square - mean * mean + h2 * (cross - mean * fisher) / 12.0, 0.0)};
}

// The entropy of returns that come from one of two components far apart (weights 1 - pe and pe,
// each density negligible where the other's returns are): each one's own, plus the choice between them.
MixtureEntropy separated(const MixtureEntropy& own, const MixtureEntropy& partner, double pe) {
  if (pe >= 1.0) return partner;
  const double own_nll = own.mean - std::log1p(-pe), partner_nll = partner.mean - std::log(pe);
  const double mean = (1.0 - pe) * own_nll + pe * partner_nll;
  const double square =
      (1.0 - pe) * (own.variance + own_nll * own_nll) + pe * (partner.variance + partner_nll * partner_nll);
  return {mean, std::max(square - mean * mean, 0.0)};
}

// E[-ln P(bin)] and its variance for one Gaussian (mean, sigma) truncated to the model's window and
// quantized to its step.
MixtureEntropy quantized_gaussian_entropy(const RangeModel& m, double mean, double sigma) {
  double entropy = 0.0;   // E[-ln P(bin)] of the quantized Gaussian
  double variance = 0.0;  // Var[-ln P(bin)]
  const double a = (m.window_min_m - mean) / sigma;
  const double b = (m.window_max_m - mean) / sigma;
  const double mass = normal_interval(a, b);
  if (mass <= 1e-300) return {};
  if (sigma >= 4.0 * m.step_m) {
    // Bins much narrower than sigma: the differential entropy of the Gaussian truncated to the
    // window, less ln(step); -ln f = const + z^2 / 2, so its variance is (E z^4 - (E z^2)^2) / 4,
    // from the truncated moments m_k = (k - 1) m_(k-2) + (a^(k-1) phi(a) - b^(k-1) phi(b)) / mass.
    const double pa = normal_pdf(a), pb = normal_pdf(b);
    const auto edge = [&](int k) {
      const double ta = std::isfinite(a) ? std::pow(a, k) * pa : 0.0;
      const double tb = std::isfinite(b) ? std::pow(b, k) * pb : 0.0;
      return (ta - tb) / mass;
    };
    const double m2 = 1.0 + edge(1);
    const double m4 = 3.0 * m2 + edge(3);
    // A bin's probability is step f (1 + step^2 f'' / 24 f) to step^4: its mean NLL gains step^2 / 24
    // times the Fisher information, 1 / sigma^2 (whole in the window; truncated, nearly so).
    const double h = m.step_m / sigma;
    entropy = 0.5 * std::log(2.0 * std::numbers::pi * sigma * sigma) + std::log(mass) + 0.5 * m2 - std::log(m.step_m) +
              h * h / 24.0;
    variance = std::max((m4 - m2 * m2) / 4.0, 0.0);
  } else {
    double second = 0.0;
    const auto first = static_cast<long>(std::floor((mean - 9.0 * sigma) / m.step_m));
    const auto last = static_cast<long>(std::ceil((mean + 9.0 * sigma) / m.step_m));
    for (long k = first; k <= last; ++k) {
      const double centre = static_cast<double>(k) * m.step_m;
      if (centre < m.window_min_m - 0.5 * m.step_m || centre > m.window_max_m + 0.5 * m.step_m) continue;
      const double q =
          normal_interval((centre - 0.5 * m.step_m - mean) / sigma, (centre + 0.5 * m.step_m - mean) / sigma) / mass;
      if (q <= 0.0) continue;
      entropy -= q * std::log(q);
      second += q * std::log(q) * std::log(q);
    }
    variance = std::max(second - entropy * entropy, 0.0);
  }
  return {entropy, variance};
}

MixtureEntropy quantized_mixture_entropy(const RangeModel& m) {
  const double partner_mean = m.mean_m + m.partner_offset_m, partner_sigma = m.partner_sigma();
  const auto whole = [&](double mean, double sigma) {
    return (m.window_min_m - mean) / sigma < -kWholeZ && (m.window_max_m - mean) / sigma > kWholeZ;
  };
  const bool partner_apart =
      m.partner_mix <= 0.0 ||
      (whole(partner_mean, partner_sigma) &&
       std::abs(m.partner_offset_m) > kOverlapSigmas * std::max({m.sigma_m, m.tail_sigma_m, partner_sigma}));
  const bool bins_narrow = std::min(m.sigma_m, m.tail_sigma_m) >= 4.0 * m.step_m;
  if (m.tail_mix > 0.0 && bins_narrow && whole(m.mean_m, m.sigma_m) && whole(m.mean_m, m.tail_sigma_m) &&
      partner_apart) {
    // The common case (a return with E2's tails, away from the range limits; at a depth edge its
    // partner's return far from it): g's bins in the narrower's sigmas, and ln(sigma / step) from
    // the change of unit; the partner's a lone Gaussian's.
    const double core = 1.0 - m.tail_mix;
    const bool core_narrower = m.sigma_m <= m.tail_sigma_m;
    const double narrow = core_narrower ? m.sigma_m : m.tail_sigma_m;
    const double h = m.step_m / narrow;
    const MixtureEntropy g = core_narrower ? two_gaussian_entropy(core, m.tail_mix, m.tail_sigma_m / m.sigma_m, h)
                                           : two_gaussian_entropy(m.tail_mix, core, m.sigma_m / m.tail_sigma_m, h);
    const MixtureEntropy own = {g.mean + std::log(narrow / m.step_m), g.variance};
    if (m.partner_mix <= 0.0) return own;
    const MixtureEntropy partner = quantized_gaussian_entropy(m, partner_mean, partner_sigma);
    return separated(own, partner, m.partner_mix);
  }
  const double own_mass = window_mass(m, m.mean_m);
  double lo = m.mean_m - 9.0 * std::max(m.sigma_m, m.tail_sigma_m);
  double hi = m.mean_m + 9.0 * std::max(m.sigma_m, m.tail_sigma_m);
  if (m.partner_mix > 0.0) {
    lo = std::min(lo, m.mean_m + m.partner_offset_m - 9.0 * m.partner_sigma());
    hi = std::max(hi, m.mean_m + m.partner_offset_m + 9.0 * m.partner_sigma());
  }
  lo = std::max(lo, m.window_min_m);
  hi = std::min(hi, m.window_max_m);
  if (hi <= lo) return {};
  const double narrowest = std::min({m.sigma_m, m.tail_mix > 0.0 ? m.tail_sigma_m : m.sigma_m, m.partner_sigma()});
  const bool narrow_bins = narrowest >= 4.0 * m.step_m;
  const double dx = std::max({narrow_bins ? 0.25 * narrowest : m.step_m, (hi - lo) / kMixturePoints, 1e-9});
  double h = 0.0, h2 = 0.0;
  // Each point's weight is the share of returns in a bin of width step centred there, q dx / step,
  // q that bin's probability under the whole mixture (gaussian_interval); narrow bins: on a grid a
  // quarter of the narrowest sigma apart (the bins' sum is the integral of the smooth q(x) / step to
  // rounding); wide bins: at their centres, the multiples of step (measured ranges are).
  const auto bin_at = [&](double x) { return gaussian_interval(m, x - 0.5 * m.step_m, x + 0.5 * m.step_m, own_mass); };
  const double first = narrow_bins ? lo + 0.5 * dx : std::round(lo / m.step_m) * m.step_m;
  for (double x = first; x < hi + 0.5 * m.step_m; x += dx) {
    const double q = bin_at(x);  // the probability of a bin of width step there
    if (q <= 0.0) continue;
    const double weight = q * dx / m.step_m;  // the share of returns there
    const double nll = -std::log(q);
    h += weight * nll;
    h2 += weight * nll * nll;
  }
  return {h, std::max(h2 - h * h, 0.0)};
}

// A return in the common case, which the diagnosis' fits score billions of times: no outlier
// component, no partner, a window that holds all of the Gaussian, a bin narrow against sigma. There
// P = p_detect phi(c) h (1 + ...) (normal_interval's midpoint rule), whose logarithm needs no exp
// and one log: -ln P = c^2 / 2 + ln sqrt(2 pi) - ln(p_detect h (1 + ...)), the same value to
// rounding (and no underflow of phi far out), which likelihood_kernels computes for many returns at
// once. The bin's centre c and width h in sigmas, or none where the full computation is needed.
struct NarrowBin {
  double c, h;
};
std::optional<NarrowBin> narrow_bin(const RangeModel& m, double measured_range_m) {
  if (!(measured_range_m > 0.0 && m.p_detect >= kImpossible && m.sigma_m > 0.0)) return std::nullopt;
  if (m.outlier_mix > 0.0 || m.partner_mix > 0.0 || m.tail_mix > 0.0) return std::nullopt;
  const double inverse_sigma = 1.0 / m.sigma_m;  // one division where the full path takes six
  if (!((m.window_min_m - m.mean_m) * inverse_sigma < -kWholeZ &&
        (m.window_max_m - m.mean_m) * inverse_sigma > kWholeZ)) {
    return std::nullopt;
  }
  const double h = m.step_m * inverse_sigma, c = (measured_range_m - m.mean_m) * inverse_sigma;
  // (h above 1e-280: the logarithm's argument stays a normal number)
  if (!(h > 1e-280 && h <= kNarrowZ && std::abs(c) * h <= 0.5)) return std::nullopt;
  return NarrowBin{c, h};
}

// A return with E2's tails and nothing else beside its Gaussian (no outliers, no partner), both
// components whole in the window and its bin narrow against the core: the full path's midpoint
// rule for each, P = (1 - t) phi(c) h (1 + ...) + t phi(c / k) (h / k) (1 + ...), k the tail's sigma
// in the core's, with two exps and one log instead of the full path's window masses and erfcs (the
// tails' candidate is fitted over every return). None where the full path is needed, or where the
// result would reach the floor (the full path applies it).
std::optional<double> tail_pixel_nll(const RangeModel& m, double measured_range_m) {
  if (!(measured_range_m > 0.0 && m.p_detect >= kImpossible && m.sigma_m > 0.0 && m.tail_mix > 0.0)) {
    return std::nullopt;
  }
  if (m.outlier_mix > 0.0 || m.partner_mix > 0.0 || !(m.tail_sigma_m >= m.sigma_m)) return std::nullopt;
  if (!((m.window_min_m - m.mean_m) / m.tail_sigma_m < -kWholeZ &&
        (m.window_max_m - m.mean_m) / m.tail_sigma_m > kWholeZ && (m.window_min_m - m.mean_m) / m.sigma_m < -kWholeZ &&
        (m.window_max_m - m.mean_m) / m.sigma_m > kWholeZ)) {
    return std::nullopt;
  }
  const double h = m.step_m / m.sigma_m, c = (measured_range_m - m.mean_m) / m.sigma_m;
  if (!(h > 1e-280 && h <= kNarrowZ && std::abs(c) * h <= 0.5)) return std::nullopt;
  const double k = m.tail_sigma_m / m.sigma_m, ht = h / k, ct = c / k;
  const double t = std::min(m.tail_mix, 1.0);
  const double p = ((1.0 - t) * std::exp(-0.5 * c * c) * h * midpoint_correction(c, h) +
                    t * std::exp(-0.5 * ct * ct) * ht * midpoint_correction(ct, ht)) /
                   std::sqrt(2.0 * std::numbers::pi);
  const double nll = -std::log(m.p_detect) - std::log(p);
  if (!(p > 0.0) || !(nll <= -std::log(kImpossible))) return std::nullopt;
  return nll;
}

// pixel_nll in full: a miss, or a return the common case leaves out.
double full_pixel_nll(const RangeModel& m, double measured_range_m) {
  if (measured_range_m <= 0.0) return -std::log(std::max(1.0 - m.p_detect, kImpossible));
  const double width = std::max(m.window_max_m - m.window_min_m, m.step_m);
  const double uniform = std::min(1.0, m.step_m / width);
  if (m.p_detect < kImpossible || m.sigma_m <= 0.0) return -std::log(kImpossible) - std::log(uniform);
  const double half = 0.5 * m.step_m;
  const double gaussian =
      gaussian_interval(m, measured_range_m - half, measured_range_m + half, window_mass(m, m.mean_m));
  const double p_range = (1.0 - m.outlier_mix) * gaussian + m.outlier_mix * uniform;
  return -std::log(m.p_detect) - std::log(std::max(p_range, kImpossible * uniform));
}

}  // namespace

double normal_cdf(double x) { return 0.5 * std::erfc(-x * kSqrtHalf); }

double normal_interval(double a, double b) {
  if (b <= a) return 0.0;
  // A window holding all of the Gaussian: the erfc differences below would round to exactly 1.
  if (a < -kWholeZ && b > kWholeZ) return 1.0;
  // A narrow interval near the centre (a quantized range bin, step << sigma): the midpoint rule with
  // its Taylor corrections, phi(c) h (1 + (c^2 - 1) h^2 / 24 + (c^4 - 6 c^2 + 3) h^4 / 1920), whose
  // relative error is about (c h)^6 / 3e5 (< 1e-7 for |c| h <= 0.5): one exp instead of two erfc,
  // in the likelihood the diagnosis' fits evaluate millions of times. Far out, erfc below.
  if (const double h = b - a, c = 0.5 * (a + b); h <= kNarrowZ && std::abs(c) * h <= 0.5) {
    return normal_pdf(c) * h * midpoint_correction(c, h);
  }
  // Take the difference on the side of the tail the interval lies in, where erfc keeps its digits.
  if (a >= 0.0) return 0.5 * (std::erfc(a * kSqrtHalf) - std::erfc(b * kSqrtHalf));
  if (b <= 0.0) return 0.5 * (std::erfc(-b * kSqrtHalf) - std::erfc(-a * kSqrtHalf));
  return 1.0 - normal_cdf(a) - (1.0 - normal_cdf(b));
}

double chi2_cdf(double x, double dof) {
  if (x <= 0.0) return 0.0;
  const double v = 2.0 / (9.0 * dof);
  return normal_cdf((std::cbrt(x / dof) - (1.0 - v)) / std::sqrt(v));
}

RangeModel range_model(const Prediction& prediction, double ideal_range_m, double wire_step_m, double reach_m) {
  RangeModel m;
  m.mean_m = ideal_range_m + prediction.bias_m;
  m.step_m = std::max(prediction.quantization_step_m, wire_step_m);
  // range_quantization folds Delta^2/12 into the variance for the emulator's moments; here the
  // interval likelihood accounts for the bins themselves, so that share comes back out.
  double variance = prediction.variance_m2;
  if (prediction.quantization_step_m > 0.0) {
    variance -= prediction.quantization_step_m * prediction.quantization_step_m / 12.0;
  }
  m.sigma_m = std::sqrt(std::max(variance, 0.0));
  // Where no surface was hit only a partner's component can return (a halo, E8): then it is the
  // pixel's one Gaussian. Elsewhere off a surface nothing returns.
  const bool partner_only = ideal_range_m <= 0.0 && prediction.partner_mix >= 1.0;
  m.p_detect = ideal_range_m > 0.0 || partner_only ? prediction.p_detect : 0.0;
  m.outlier_mix = prediction.outlier_mix;
  m.partner_mix = prediction.partner_mix;
  m.partner_offset_m = prediction.partner_offset_m;
  if (prediction.partner_extra_variance_m2 != 0.0) {
    m.partner_sigma_m = std::sqrt(std::max(variance + prediction.partner_extra_variance_m2, 1e-10));
  }
  if (prediction.tail_mix > 0.0 && !partner_only) {
    m.tail_mix = std::min(prediction.tail_mix, 1.0);
    m.tail_sigma_m = std::sqrt(std::max(variance + prediction.tail_extra_variance_m2, 1e-10));
  }
  if (partner_only) {
    m.mean_m += m.partner_offset_m;
    m.sigma_m = m.partner_sigma();
    m.partner_mix = m.partner_offset_m = m.partner_sigma_m = 0.0;
  }
  m.window_min_m = prediction.window_min_m;
  m.window_max_m = std::min(prediction.window_max_m, reach_m);
  return m;
}

double partner_share(const RangeModel& m) {
  if (m.partner_mix <= 0.0 || m.sigma_m <= 0.0) return 0.0;
  const double own = (1.0 - m.partner_mix) * window_mass(m, m.mean_m);
  const double partner = m.partner_mix * window_mass(m, m.mean_m + m.partner_offset_m, m.partner_sigma());
  return own + partner > 0.0 ? partner / (own + partner) : 0.0;
}

void pixel_nlls(std::span<const RangeModel> models, std::span<const double> measured, std::span<double> out) {
  assert(measured.size() == models.size() && out.size() == models.size());
  struct Batch {  // the common case's returns, gathered for the kernel
    std::vector<double> c, h, p_detect, nll;
    std::vector<size_t> index;
  };
  thread_local Batch b;
  b.c.clear();
  b.h.clear();
  b.p_detect.clear();
  b.index.clear();
  for (size_t i = 0; i < models.size(); ++i) {
    if (const std::optional<NarrowBin> bin = narrow_bin(models[i], measured[i])) {
      b.c.push_back(bin->c);
      b.h.push_back(bin->h);
      b.p_detect.push_back(models[i].p_detect);
      b.index.push_back(i);
    } else if (const std::optional<double> tail = tail_pixel_nll(models[i], measured[i])) {
      out[i] = *tail;
    } else {
      out[i] = full_pixel_nll(models[i], measured[i]);
    }
  }
  b.nll.resize(b.c.size());
  analysis_detail::narrow_bin_nlls(b.c.data(), b.h.data(), b.p_detect.data(), b.nll.data(), b.c.size());
  // Above -ln(kImpossible) the range's probability may be floored (kImpossible * uniform): the full
  // computation decides.
  const double floor_free = -std::log(kImpossible);
  for (size_t j = 0; j < b.index.size(); ++j) {
    const size_t i = b.index[j];
    out[i] = b.nll[j] <= floor_free ? b.nll[j] : full_pixel_nll(models[i], measured[i]);
  }
}

double pixel_nll(const RangeModel& m, double measured_range_m) {
  double nll = 0.0;
  pixel_nlls({&m, 1}, {&measured_range_m, 1}, {&nll, 1});
  return nll;
}

PixelScore score_pixel(const RangeModel& m, double measured_range_m, double pit_draw) {
  PixelScore score;
  if (measured_range_m <= 0.0) {
    const double p_miss = 1.0 - m.p_detect;
    score.impossible = p_miss < kImpossible;
    score.nll = -std::log(std::max(p_miss, kImpossible));
    return score;
  }
  const double width = std::max(m.window_max_m - m.window_min_m, m.step_m);
  const double uniform = std::min(1.0, m.step_m / width);  // one bin of the outlier component
  if (m.p_detect < kImpossible || m.sigma_m <= 0.0) {
    score.impossible = true;
    score.nll = -std::log(kImpossible) - std::log(uniform);
    score.pit = pit_draw;
    return score;
  }
  const double half = 0.5 * m.step_m;
  const double mass = window_mass(m, m.mean_m);
  const double gaussian = gaussian_interval(m, measured_range_m - half, measured_range_m + half, mass);
  double p_range = (1.0 - m.outlier_mix) * gaussian + m.outlier_mix * uniform;
  if (p_range < kImpossible * uniform) {
    score.impossible = true;
    p_range = kImpossible * uniform;
  }
  score.nll = -std::log(m.p_detect) - std::log(p_range);
  const TruncatedMoments t =
      truncated_moments((m.window_min_m - m.mean_m) / m.sigma_m, (m.window_max_m - m.mean_m) / m.sigma_m, mass);
  score.mean_m = m.mean_m + m.sigma_m * t.mean;
  score.sd_m = m.sigma_m * t.sd;
  score.z = (measured_range_m - score.mean_m) / score.sd_m;
  const double below = range_cdf(m, measured_range_m - half, mass);
  const double above = range_cdf(m, measured_range_m + half, mass);
  score.pit = below + pit_draw * (above - below);
  return score;
}

NllMoments expected_nll(const RangeModel& m) {
  if (m.p_detect <= 0.0 || m.sigma_m <= 0.0) return {};
  const double p = std::min(m.p_detect, 1.0);
  const double miss_nll = -std::log(std::max(1.0 - p, kImpossible));
  const double hit_nll = -std::log(p);
  if (window_mass(m, m.mean_m) <= 1e-300) return {};
  // The partner's component (E6's edge partner, E8's halo), partner_offset_m away, taken as apart
  // from the pixel's own (its offset is a depth step, many sigmas): choosing between the two adds
  // their mixing entropy, and the choice's own spread to the variance.
  MixtureEntropy range;
  if (m.tail_mix > 0.0) {
    range = quantized_mixture_entropy(m);
  } else if (partner_overlaps(m) && std::min(m.sigma_m, m.partner_sigma()) >= 4.0 * m.step_m) {
    // Overlapping components (a halo on the retroreflector's own board, a small depth step): the
    // mixture's density, not two separate Gaussians and the choice between them.
    range = mixture_entropy(m);
    range.mean -= std::log(m.step_m);
  } else {
    range = quantized_gaussian_entropy(m, m.mean_m, m.sigma_m);
    if (m.partner_mix > 0.0) {
      range = separated(range, quantized_gaussian_entropy(m, m.mean_m + m.partner_offset_m, m.partner_sigma()),
                        m.partner_mix);
    }
  }
  const double entropy = range.mean, variance = range.variance;
  // The outlier component: a return is Gaussian with weight 1 - pi, costing its bin's NLL less
  // ln(1 - pi), or uniform with weight pi, costing -ln(pi * step / width) (each density negligible
  // where the other dominates, which holds for the small weights effects give it).
  const double pi = std::clamp(m.outlier_mix, 0.0, 1.0);
  double range_mean = entropy, range_square = variance + entropy * entropy;
  if (pi > 0.0) {
    const double width = std::max(m.window_max_m - m.window_min_m, m.step_m);
    const double gaussian = entropy - std::log1p(-std::min(pi, 1.0 - 1e-12));
    const double uniform = -std::log(pi * std::min(1.0, m.step_m / width));
    range_mean = (1.0 - pi) * gaussian + pi * uniform;
    range_square = (1.0 - pi) * (variance + gaussian * gaussian) + pi * uniform * uniform;
  }
  NllMoments moments;
  moments.mean = (1.0 - p) * miss_nll + p * (hit_nll + range_mean);
  const double square =
      (1.0 - p) * miss_nll * miss_nll + p * (hit_nll * hit_nll + 2.0 * hit_nll * range_mean + range_square);
  moments.variance = std::max(square - moments.mean * moments.mean, 0.0);
  return moments;
}

}  // namespace lidartwin
