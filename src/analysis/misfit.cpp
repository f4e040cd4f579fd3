// Scores, bins and tests (lidar-physics.md 3.2-3.3): where the measured pixels leave the model.
#include "lidartwin/analysis/misfit.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <set>

#include <fmt/format.h>

#include "analysis/misfit_features.h"
#include "analysis/percent_text.h"
#include "lidartwin/analysis/pixel_likelihood.h"
#include "lidartwin/random/counter_rng.h"

namespace lidartwin {
namespace {

constexpr int kPitBins = 20;

using analysis_detail::expected_outlier_share;
using analysis_detail::f64;
using analysis_detail::Feature;
using analysis_detail::Features;
using analysis_detail::inlier_z2;
using analysis_detail::kMinTested;
using analysis_detail::kOutlierZ;
using analysis_detail::make_features;
using analysis_detail::model_of;
using analysis_detail::percent;

// The binnings reported: each feature alone, and the pairs the physics says interact (3.2).
std::vector<std::vector<std::string>> binnings(const Features& f, PixelTable::Reference reference) {
  std::vector<std::vector<std::string>> out;
  for (const char* name : {"range", "incidence", "reflectivity", "signal", "near_ir", "beam", "azimuth", "time", "edge",
                           "retro", "material"}) {
    if (f.by_name.count(name)) out.push_back({name});
  }
  out.push_back({"range", "incidence"});
  out.push_back({"range", "reflectivity"});
  out.push_back({"range", "beam_group"});
  out.push_back({"azimuth", "range"});
  out.push_back({"range", "edge"});
  // Without a scene what needs its surfaces is unknown: static mode knows no surface at all, map
  // mode knows the surface's normal (incidence) but no materials, and leaves out pixels near edges.
  if (reference != PixelTable::Reference::kScene) {
    const bool keep_incidence = reference == PixelTable::Reference::kMap;
    std::erase_if(out, [&](const std::vector<std::string>& names) {
      return std::ranges::any_of(names, [&](const std::string& n) {
        return (n == "incidence" && !keep_incidence) || n == "material" || n == "retro" || n == "edge";
      });
    });
  }
  return out;
}

// ---- accumulation --------------------------------------------------------------------------------

struct Acc {
  size_t pixels = 0, returns = 0, inliers = 0, outliers = 0;
  double pd = 0, pd_var = 0;
  double z = 0, e = 0, eb = 0, eb2 = 0, bias = 0, sigma2 = 0, sheppard = 0;
  double wz2 = 0;                          // weighted z^2 less the reference's share (add_pixel)
  double model_dof = 0;                    // what wz2 is under the model (ratio^2 = wz2 / model_dof)
  double weight = 0;                       // the ratio's weights' sum (a mean z's share of wz2)
  double dof_weight = 0, dof_weight2 = 0;  // the spread's degrees of freedom, (sum)^2 / sum2
  double z2 = 0;                           // E[z^2] of the inliers under the model (the bias test's variance)
  double z2_variance = 0;                  // the sum of Var[z^2]: how far z^2 is from chi-square
  double reference2 = 0;                   // the reference's own variance (map mode), taken out of the spreads
  double weighted_sigma2 = 0;              // sigma_model^2 weighted as the ratio weighs (map mode's spread_m)
  double outliers_expected = 0;
  double nll = 0, nll_expected = 0;
};

// What a return adds to every bin it falls in that costs a model to work out (the outlier share the
// model expects, an inlier's E[z^2]): worked out once per pixel, not once per binning (16 of them).
struct ReturnTerms {
  std::vector<double> outliers_expected;
  std::vector<double> z2, z4;
  ReturnTerms(const PixelTable& t, const PixelScores& s)
      : outliers_expected(t.size(), 0.0), z2(t.size(), 1.0), z4(t.size(), 3.0) {
    for (size_t i = 0; i < t.size(); ++i) {
      if (t.ideal_range_m[i] <= 0.0f || t.range_m[i] <= 0.0f) continue;
      outliers_expected[i] = expected_outlier_share(t, i);
      if (!s.impossible[i] && std::abs(f64(s.z[i])) <= kOutlierZ) {
        const analysis_detail::InlierMoments m = analysis_detail::inlier_moments(t, i);
        z2[i] = m.z2;
        z4[i] = m.z4;
      }
    }
  }
};

void add_pixel(Acc& a, const PixelTable& t, const PixelScores& s, const ReturnTerms& terms, size_t i) {
  const double pd = f64(t.p_detect[i]);
  ++a.pixels;
  a.pd += pd;
  a.pd_var += pd * (1.0 - pd);
  a.nll += f64(s.nll[i]);
  a.nll_expected += f64(s.nll_expected[i]);
  if (t.range_m[i] <= 0.0f) return;
  ++a.returns;
  a.outliers_expected += terms.outliers_expected[i];
  const double z = f64(s.z[i]);
  if (s.impossible[i] || std::abs(z) > kOutlierZ) {
    ++a.outliers;
    return;
  }
  ++a.inliers;
  const double e = (f64(t.range_m[i])) - f64(t.ideal_range_m[i]);
  const double bias = f64(s.mean_m[i]) - f64(t.ideal_range_m[i]);  // bias + the window's shift
  const double sigma = f64(s.sd_m[i]);
  const double w = t.dof_share(i);
  a.z += z;
  // A map reference's own error (variance v, PixelTable::reference_variance_m2) is in the
  // likelihood's sigma, sd = sqrt(sigma_model^2 + v), and in the measured residual. The spread judged
  // is the sensor's own: with s = v / sd^2, (z^2 - s) / (1 - s) has mean sigma_true^2 / sigma_model^2
  // for each pixel. Left in, v would pull a wrong model's ratio toward 1 (sd^2 and the residual's
  // variance share it), by 10 % where sigma is twice the model's and v a tenth of it. The bin's
  // ratio is a weighted mean of those: weight 1, the plain mean the scene's residuals give, where the
  // reference holds at most half of sd^2; beyond, weights falling as 2 (1 - s), since a pixel whose
  // reference is most of its residual says little about the sensor. (The ratio of sums, weights
  // 1 - s throughout, under-weighed the pixels where a missing effect grows with what makes v large:
  // incidence for E4, weak signal for E2: 0.96 of the scene's on the plant at 5-8 m.)
  const double reference2 = f64(t.reference_variance_m2[i]);
  const double reference_share = std::min(reference2 / (sigma * sigma), 1.0);
  const double weight = w * std::min(1.0 / std::max(1.0 - reference_share, 1e-12), 2.0);
  // E[z^2] of an inlier is 1 under the model, more where E2's tails put some returns inside too;
  // the range bins add step^2 / 12 to every component's variance (Sheppard), so to z^2: a sum, not
  // a factor 1 + step^2 / 12 sigma^2 on E[z^2], which would scale the bins' share with the tails'.
  const double z2 = terms.z2[i];
  const double sheppard = f64(t.step_m[i]) * f64(t.step_m[i]) / (12.0 * sigma * sigma);
  a.z2 += z2;
  a.z2_variance += std::max(terms.z4[i] - z2 * z2, 0.0);
  a.wz2 += weight * (z * z - reference_share);
  a.model_dof += weight * (z2 + sheppard - reference_share);
  a.weight += weight;
  // The ratio's degrees of freedom: (sum of weights)^2 / sum of their squares, z^2 counting 1 each.
  a.dof_weight += weight * (1.0 - reference_share);
  if (w > 0.0) a.dof_weight2 += weight * weight / w;
  a.reference2 += reference2;
  a.weighted_sigma2 += weight * (1.0 - reference_share) * z2 * (sigma * sigma - reference2);
  a.e += e;
  a.eb += e - bias;
  a.eb2 += (e - bias) * (e - bias);
  a.bias += bias;
  a.sigma2 += z2 * sigma * sigma;
  a.sheppard += sheppard;
}

// ---- tests ---------------------------------------------------------------------------------------

double two_sided_normal(double t) { return std::erfc(std::abs(t) / std::sqrt(2.0)); }

// Two-sided p of observing k events where lambda are expected (Poisson; normal beyond 200).
double poisson_two_sided(double k, double lambda) {
  if (lambda <= 0.0) return k > 0.0 ? 0.0 : 1.0;
  if (lambda > 200.0) return two_sided_normal((k - lambda) / std::sqrt(lambda));
  const auto pmf = [lambda](double j) { return std::exp(j * std::log(lambda) - lambda - std::lgamma(j + 1.0)); };
  // The tail k lies in, summed directly: its complement, 1 - (a sum that rounds to 1), can come out
  // below 0, which reads as "not tested", in exactly the bins that misfit most.
  double below = 0.0;  // P(X <= k)
  double above = 0.0;  // P(X >= k)
  if (k <= lambda) {
    for (double j = 0.0; j <= k; j += 1.0) below += pmf(j);
    above = 1.0 - below + pmf(k);
  } else {  // terms fall from j = k on
    for (double j = k, term = pmf(j); term > above * 1e-17 && j < k + 1e4; j += 1.0, term = pmf(j)) above += term;
    below = 1.0 - above + pmf(k);
  }
  return std::clamp(2.0 * std::min(below, above), 0.0, 1.0);
}

double bernoulli_kl(double p, double q) {
  const auto term = [](double a, double b) { return a > 0.0 ? a * std::log(a / std::max(b, 1e-12)) : 0.0; };
  return term(p, q) + term(1.0 - p, 1.0 - q);
}

struct RawTests {
  double bias = -1, spread = -1, detection = -1, outliers = -1;  // -1: not tested
};

// The spread's ratio^2 to the model's: residuals about a temporal mean weigh by their share of the
// degrees of freedom (1 elsewhere).
double spread_ratio2(const Acc& a) {
  const double z_mean = a.z / static_cast<double>(a.inliers);
  return std::max(a.wz2 - a.weight * z_mean * z_mean, 0.0) / a.model_dof;
}

// Its degrees of freedom. A Gaussian's z^2 has variance 2 E[z^2]^2; E2's tails give it more (a
// mixture's z^2 is heavy tailed), and the chi-square's degrees of freedom shrink by as much
// (Satterthwaite).
double spread_dof(const Acc& a) {
  const auto n = static_cast<double>(a.inliers);
  const double heavier = a.z2 > 0.0 ? std::max(n * a.z2_variance / (2.0 * a.z2 * a.z2), 1.0) : 1.0;
  return a.dof_weight * a.dof_weight / a.dof_weight2 / heavier;
}

BinMisfit summarize(const Acc& a, RawTests& raw) {
  BinMisfit b;
  b.pixels = a.pixels;
  b.returns = a.returns;
  b.inliers = a.inliers;
  b.nll = a.nll;
  b.nll_expected = a.nll_expected;
  if (a.pixels > 0) {
    b.detection_measured = static_cast<double>(a.returns) / static_cast<double>(a.pixels);
    b.detection_predicted = a.pd / static_cast<double>(a.pixels);
    b.misfit_detection = static_cast<double>(a.pixels) * bernoulli_kl(b.detection_measured, b.detection_predicted);
  }
  if (a.pixels >= kMinTested) {
    const double misses = static_cast<double>(a.pixels - a.returns);
    const double expected_misses = static_cast<double>(a.pixels) - a.pd;
    raw.detection = a.pd_var < 25.0 ? poisson_two_sided(misses, expected_misses)
                                    : two_sided_normal((static_cast<double>(a.returns) - a.pd) / std::sqrt(a.pd_var));
  }
  if (a.returns > 0) {
    b.outliers_measured = static_cast<double>(a.outliers) / static_cast<double>(a.returns);
    b.outliers_predicted = a.outliers_expected / static_cast<double>(a.returns);
    const double o = static_cast<double>(a.outliers), l = a.outliers_expected;
    b.misfit_outliers = (o > 0.0 ? o * std::log(o / std::max(l, 1e-12)) : 0.0) - (o - l);
    if (a.returns >= kMinTested) raw.outliers = poisson_two_sided(o, l);
  }
  if (a.inliers > 0) {
    const auto n = static_cast<double>(a.inliers);
    b.bias_measured_m = a.e / n;
    b.bias_predicted_m = a.bias / n;
    b.spread_measured_m = std::sqrt(std::max(a.eb2 / n - (a.eb / n) * (a.eb / n) - a.reference2 / n, 0.0));
    b.spread_predicted_m = std::sqrt(std::max(a.sigma2 - a.reference2, 0.0) / n);
    // z's variance under the model: E[z^2] of an inlier (E2's tails' returns inside count,
    // inlier_moments) and the range bins' step^2 / 12 (Sheppard); the spread's ratio has both in
    // model_dof.
    const double v_bias = (a.z2 + a.sheppard) / n;
    const double z_mean = a.z / n;
    const double ratio2 = spread_ratio2(a);
    b.spread_ratio = std::sqrt(ratio2);
    if (a.reference2 > 0.0 && a.dof_weight > 0.0) {
      // Map mode: the millimetres as the ratio weighs its pixels. Unweighted, the few returns whose
      // reference is most of their residual (v of centimetres, weight near 0 in the ratio) decided
      // them, and a bin whose spread was 3.8 times the model's read "0.0 mm against 0.0 mm".
      b.spread_predicted_m = std::sqrt(a.weighted_sigma2 / a.dof_weight);
      b.spread_measured_m = b.spread_ratio * b.spread_predicted_m;
    }
    b.misfit_bias = n * z_mean * z_mean / (2.0 * v_bias);
    b.misfit_spread = ratio2 > 0.0 ? n * (-0.5 * std::log(ratio2) + 0.5 * ratio2 - 0.5) : 0.0;
    if (a.inliers >= kMinTested) {
      raw.bias = two_sided_normal(a.z / std::sqrt(n * v_bias));
      const double dof = spread_dof(a);
      const double cdf = chi2_cdf(dof * ratio2, dof - 1.0);
      raw.spread = std::min(1.0, 2.0 * std::min(cdf, 1.0 - cdf));
    }
  }
  return b;
}

// ---- a pair given its single features --------------------------------------------------------

// Two-sided p of k successes in n trials of probability q (normal where n q (1 - q) > 200).
double binomial_two_sided(double k, double n, double q) {
  if (n <= 0.0 || q <= 0.0 || q >= 1.0) return 1.0;
  if (n * q * (1.0 - q) > 200.0) return two_sided_normal((k - n * q) / std::sqrt(n * q * (1.0 - q)));
  const auto pmf = [&](double j) {
    return std::exp(std::lgamma(n + 1.0) - std::lgamma(j + 1.0) - std::lgamma(n - j + 1.0) + j * std::log(q) +
                    (n - j) * std::log1p(-q));
  };
  double below = 0.0, above = 0.0;
  for (double j = 0.0; j <= k; j += 1.0) below += pmf(j);
  for (double j = k; j <= n; j += 1.0) above += pmf(j);
  return std::clamp(2.0 * std::min(below, above), 0.0, 1.0);
}

// A pair's bin (range 20-35 m within azimuth 315-360 degrees) is a part of each of its features'
// single bins. Where a single bin fails, its pair bins fail with it at their share of the
// pixels, and say nothing the single does not: the question is whether the pair departs from
// the single's own measured level, the single taken as the model. Tested as that, with the part's
// covariance with its whole taken out: the pair's count given the single's (binomial, exact), its
// mean z against the single's (variance v (1/n_pair - 1/n_single)), its spread's ratio against the
// single's (the chi-square's degrees of freedom grown by 1 / (1 - n_pair / n_single)).
RawTests given_single(const Acc& pair, const Acc& single) {
  RawTests raw;
  if (pair.pixels >= kMinTested && single.pixels > pair.pixels) {
    const double misses = static_cast<double>(pair.pixels - pair.returns);
    const double single_misses = static_cast<double>(single.pixels - single.returns);
    const double expected = static_cast<double>(pair.pixels) - pair.pd;
    const double single_expected = static_cast<double>(single.pixels) - single.pd;
    raw.detection = single_expected > 0.0 ? binomial_two_sided(misses, single_misses, expected / single_expected) : 1.0;
  }
  if (pair.returns >= kMinTested && single.returns > pair.returns && single.outliers_expected > 0.0) {
    raw.outliers = binomial_two_sided(static_cast<double>(pair.outliers), static_cast<double>(single.outliers),
                                      pair.outliers_expected / single.outliers_expected);
  }
  if (pair.inliers >= kMinTested && single.inliers > pair.inliers) {
    const auto n = static_cast<double>(pair.inliers), n_single = static_cast<double>(single.inliers);
    const double share = n / n_single;
    const double v = (pair.z2 + pair.sheppard) / n;
    raw.bias = two_sided_normal((pair.z / n - single.z / n_single) / std::sqrt(v * (1.0 / n - 1.0 / n_single)));
    const double ratio2 = spread_ratio2(pair), single_ratio2 = spread_ratio2(single);
    if (single_ratio2 > 0.0) {
      const double dof = spread_dof(pair) / (1.0 - share);
      const double cdf = chi2_cdf(dof * ratio2 / single_ratio2, dof - 1.0);
      raw.spread = std::min(1.0, 2.0 * std::min(cdf, 1.0 - cdf));
    }
  }
  return raw;
}

// ---- words ---------------------------------------------------------------------------------------

std::string millimetres(double m) {
  const double mm = m * 1000.0;
  return std::abs(mm) < 10.0 ? fmt::format("{:.1f} mm", mm) : fmt::format("{:.0f} mm", mm);
}
std::string signed_millimetres(double m) { return (m >= 0 ? "+" : "") + millimetres(m); }

std::string sentence(const FailingRegion& f, const BinMisfit& b) {
  const std::string where = describe(f.region);
  const std::string count = fmt::format("{} pixels", b.pixels);
  if (f.quantity == "bias") {
    const double diff = b.bias_measured_m - b.bias_predicted_m;
    return fmt::format("{}: the measured range is {} {} than the model's (bias {} against {}; {})", where,
                       millimetres(std::abs(diff)), diff > 0 ? "longer" : "shorter",
                       signed_millimetres(b.bias_measured_m), signed_millimetres(b.bias_predicted_m), count);
  }
  if (f.quantity == "spread") {
    return fmt::format("{}: the measured spread is {:.2g} times the model's ({} against {}; {})", where, b.spread_ratio,
                       millimetres(b.spread_measured_m), millimetres(b.spread_predicted_m), count);
  }
  if (f.quantity == "detection") {
    // Where nearly every pixel returns, the misses say it: a handful against a fraction of one.
    const auto pixels = static_cast<double>(b.pixels);
    const double misses = std::round(pixels * (1.0 - b.detection_measured));
    const std::string missed =
        b.detection_predicted > 0.99
            ? fmt::format("{:.0f} misses, the model expects {:.3g}; ", misses, pixels * (1.0 - b.detection_predicted))
            : "";
    return fmt::format("{}: {} of pixels return, the model expects {} ({}{})", where, percent(b.detection_measured),
                       percent(b.detection_predicted), missed, count);
  }
  return fmt::format("{}: {} of returns lie beyond 5 sigma, the model expects {} ({} returns)", where,
                     percent(b.outliers_measured), percent(b.outliers_predicted), b.returns);
}

std::string number(double v) {
  if (v == std::floor(v) && std::abs(v) < 1e6) return fmt::format("{:.0f}", v);
  return fmt::format("{:.3g}", v);
}

// A pair region that fails no more strongly than one of its features alone adds little to the
// single feature ("range 13-20 m, beams 16-23" when all of 13-20 m fails a little more there): it
// is dropped, so the report names the feature the misfit follows. A pair is kept when it fails at
// least 1.5 times as strongly per pixel as each of its failing single-feature regions (and, tested
// before, departs from each of them by more than chance: given_single).
void drop_explained_pairs(std::vector<FailingRegion>& failing) {
  std::map<std::pair<std::string, std::string>, double> single;  // (quantity, "name lo hi") -> per pixel
  const auto key = [](const std::string& quantity, const std::pair<std::string, std::array<double, 2>>& f) {
    return std::make_pair(quantity, fmt::format("{} {} {}", f.first, f.second[0], f.second[1]));
  };
  for (const FailingRegion& f : failing) {
    if (f.region.size() == 1) single[key(f.quantity, f.region[0])] = f.misfit_per_pixel;
  }
  std::erase_if(failing, [&](const FailingRegion& f) {
    if (f.region.size() < 2) return false;
    for (const auto& feature : f.region) {
      const auto it = single.find(key(f.quantity, feature));
      if (it != single.end() && f.misfit_per_pixel < 1.5 * it->second) return true;
    }
    return false;
  });
}

// "at depth edges", "1 px from a depth edge", "3–5 px from a depth edge", "more than 5 px from a
// depth edge".
std::string distance_words(double lo, double hi, const char* on, const char* what) {
  if (hi <= 0.0) return on;
  if (lo >= PixelTable::kFarPixels) return fmt::format("more than {} px from {}", PixelTable::kFarPixels - 1, what);
  if (lo == hi) return fmt::format("{} px from {}", number(lo), what);
  return fmt::format("{}–{} px from {}", number(lo), number(hi), what);
}

}  // namespace

std::string describe(const Region& region) {
  std::vector<std::string> parts;
  for (const auto& [name, range] : region) {
    const auto [lo, hi] = range;
    const auto span = [&](const char* what, const char* unit, double top) {
      if (hi >= top) return fmt::format("{} above {}{}", what, number(lo), unit);
      if (lo <= 0.0 && name != "beam" && name != "beam_group")
        return fmt::format("{} below {}{}", what, number(hi), unit);
      return fmt::format("{} {}–{}{}", what, number(lo), number(hi), unit);
    };
    if (name == "range") parts.push_back(span("range", " m", 1e3));
    else if (name == "incidence") parts.push_back(span("incidence", "°", 90.0));
    else if (name == "reflectivity") parts.push_back(span("reflectivity", " %", 1e3));
    else if (name == "signal") parts.push_back(span("expected signal", " photons", 1e6));
    else if (name == "near_ir") parts.push_back(span("expected near-IR", " photons", 1e6));
    else if (name == "azimuth") parts.push_back(fmt::format("azimuth {}–{}°", number(lo), number(hi)));
    else if (name == "time") parts.push_back(fmt::format("time {:.2f}–{:.2f} s", lo, hi));
    else if (name == "edge") parts.push_back(distance_words(lo, hi, "at depth edges", "a depth edge"));
    else if (name == "retro") parts.push_back(distance_words(lo, hi, "on retroreflectors", "a retroreflector"));
    else if (name == "material") parts.push_back(fmt::format("material {}", number(lo)));
    else if (lo == hi) parts.push_back(fmt::format("beam {}", number(lo)));
    else parts.push_back(fmt::format("beams {}–{}", number(lo), number(hi)));
  }
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) out += (i ? ", " : "") + parts[i];
  return out;
}

PixelScores score_pixels(const PixelTable& t, uint64_t seed, WorkerPool* pool) {
  PixelScores s;
  score_pixels(t, seed, pool, s);
  return s;
}

void score_pixels(const PixelTable& t, uint64_t seed, WorkerPool* pool, PixelScores& s) {
  const size_t n = t.size();
  s.nll.resize(n);
  s.z.resize(n);
  s.pit.resize(n);
  s.impossible.resize(n);
  s.mean_m.resize(n);
  s.sd_m.resize(n);
  s.nll_expected.resize(n);
  s.nll_variance.resize(n);
  for_each_pixel_chunk(n, pool, [&](size_t first, size_t last) {
    for (size_t i = first; i < last; ++i) {
      const RangeModel model = model_of(t, i);
      // The PIT draw is keyed by the pixel, so reports repeat exactly (DESIGN.md: counter-based noise).
      RandomStream draw(seed, PixelKey{t.frame[i], t.column[i], t.beam[i]}, 0x5049545Fu);
      const PixelScore score = score_pixel(model, f64(t.range_m[i]), draw.uniform(0));
      s.nll[i] = static_cast<float>(score.nll);
      s.z[i] = static_cast<float>(score.z);
      s.pit[i] = t.range_m[i] > 0.0f ? static_cast<float>(score.pit) : -1.0f;
      s.impossible[i] = score.impossible ? 1 : 0;
      s.mean_m[i] = static_cast<float>(score.mean_m);
      s.sd_m[i] = static_cast<float>(score.sd_m);
      const NllMoments moments = expected_nll(model);
      s.nll_expected[i] = static_cast<float>(moments.mean);
      s.nll_variance[i] = static_cast<float>(moments.variance);
    }
  });
}

Misfit find_misfit(const PixelTable& t, const PixelScores& s, size_t frames, const MisfitOptions& options) {
  const double alpha = options.alpha;
  Misfit out;
  MisfitSummary& sum = out.summary;
  sum.frames = frames;
  sum.pixels = t.size();
  double nll = 0, nll_expected = 0, nll_variance = 0, hits = 0, pd = 0, z = 0, z2 = 0, inliers = 0;
  std::vector<double> pit(kPitBins, 0.0);
  double pit_count = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    nll += f64(s.nll[i]);
    nll_expected += f64(s.nll_expected[i]);
    nll_variance += f64(s.nll_variance[i]);
    const bool returned = t.range_m[i] > 0.0f;
    sum.returns += returned ? 1 : 0;
    if (t.ideal_range_m[i] > 0.0f) {
      hits += 1;
      pd += f64(t.p_detect[i]);
      sum.detection_measured += returned ? 1 : 0;
    }
    if (s.impossible[i]) (returned ? sum.unexpected_returns : sum.impossible_misses) += 1;
    if (returned && !s.impossible[i]) {
      pit[std::min(kPitBins - 1, static_cast<int>(f64(s.pit[i]) * kPitBins))] += 1;
      pit_count += 1;
      if (std::abs(f64(s.z[i])) <= kOutlierZ) {
        z += f64(s.z[i]);
        z2 += (f64(s.z[i])) * f64(s.z[i]);
        inliers += 1;
      }
    }
  }
  const auto n = static_cast<double>(std::max<size_t>(t.size(), 1));
  sum.nll_per_pixel = nll / n;
  sum.nll_expected = nll_expected / n;
  sum.nll_se = std::sqrt(nll_variance) / n;
  sum.detection_measured = hits > 0 ? sum.detection_measured / hits : 0.0;
  sum.detection_predicted = hits > 0 ? pd / hits : 0.0;
  if (inliers > 0) {
    sum.z_mean = z / inliers;
    sum.z_std = std::sqrt(std::max(z2 / inliers - sum.z_mean * sum.z_mean, 0.0));
  }
  double chi2 = 0.0;
  for (double& count : pit) {
    const double expected = pit_count / kPitBins;
    if (expected > 0) chi2 += (count - expected) * (count - expected) / expected;
    count = pit_count > 0 ? count / pit_count : 0.0;
  }
  sum.pit_histogram = pit;
  sum.pit_uniformity_p = pit_count > 0 ? 1.0 - chi2_cdf(chi2, kPitBins - 1) : 1.0;

  // Every binning: accumulate over pixels that meet a surface, then summarize and test.
  const Features features = make_features(t);
  const ReturnTerms terms(t, s);
  // Each feature's bin of each pixel that meets a surface (-1: none), found once: range alone is in
  // six binnings.
  std::map<const Feature*, std::vector<int16_t>> bins_of;
  const auto bins = [&](const Feature* f) -> const std::vector<int16_t>& {
    std::vector<int16_t>& b = bins_of[f];
    if (b.empty()) {
      b.assign(t.size(), -1);
      for (size_t i = 0; i < t.size(); ++i) {
        if (t.ideal_range_m[i] > 0.0f) b[i] = static_cast<int16_t>(f->bin(f->value(i)));
      }
    }
    return b;
  };
  std::vector<RawTests> raw;
  // Each single feature's bins' sums ("azimuth", bin) and, for each pair bin, its tests given each
  // of its two features' single bins (given_single), and those bins' keys.
  using BinKey = std::pair<std::string, int>;
  std::map<BinKey, Acc> singles;
  struct PairTests {
    std::array<BinKey, 2> single;
    std::array<RawTests, 2> given;
  };
  std::vector<PairTests> pair_tests;
  for (const auto& names : binnings(features, t.reference)) {
    std::vector<const Feature*> fs;
    for (const auto& name : names) fs.push_back(&features[name]);
    const int n2 = fs.size() > 1 ? fs[1]->bins() : 1;
    std::vector<Acc> acc(static_cast<size_t>(fs[0]->bins() * n2));
    const std::vector<int16_t>& first = bins(fs[0]);
    const std::vector<int16_t>* second = fs.size() > 1 ? &bins(fs[1]) : nullptr;
    for (size_t i = 0; i < t.size(); ++i) {
      const int k0 = first[i];
      const int k1 = second ? (*second)[i] : 0;
      if (k0 < 0 || k1 < 0) continue;
      add_pixel(acc[static_cast<size_t>(k0 * n2 + k1)], t, s, terms, i);
    }
    for (size_t k = 0; k < acc.size(); ++k) {
      if (acc[k].pixels == 0) continue;
      RawTests tests;
      BinMisfit bin = summarize(acc[k], tests);
      if (t.reference == PixelTable::Reference::kTemporalMean) tests.bias = -1;  // the mean is the data's own
      if (t.reference == PixelTable::Reference::kMap) tests.detection = -1;      // returns only
      const auto k0 = static_cast<int>(k) / n2, k1 = static_cast<int>(k) % n2;
      const auto public_name = [](const std::string& name) {
        return name == "beam_group" ? std::string("beam") : name;
      };
      bin.region.emplace_back(public_name(fs[0]->name), fs[0]->range_of(k0));
      if (fs.size() > 1) bin.region.emplace_back(public_name(fs[1]->name), fs[1]->range_of(k1));
      out.bins.push_back(std::move(bin));
      raw.push_back(tests);
      PairTests pair;
      if (fs.size() == 1) {
        pair.single[0] = {fs[0]->name, k0};
        singles[pair.single[0]] = acc[k];
      } else {
        pair.single = {BinKey{fs[0]->name, k0}, BinKey{fs[1]->name, k1}};
        for (size_t j = 0; j < 2; ++j) {
          const auto it = singles.find(pair.single[j]);
          if (it != singles.end()) pair.given[j] = given_single(acc[k], it->second);
        }
      }
      pair_tests.push_back(std::move(pair));
    }
  }
  // Bonferroni over every test made.
  for (const RawTests& r : raw) sum.tests += (r.bias >= 0) + (r.spread >= 0) + (r.detection >= 0) + (r.outliers >= 0);
  const double m = static_cast<double>(std::max<size_t>(sum.tests, 1));
  const auto corrected = [m](double p) { return p < 0 ? 1.0 : std::min(1.0, p * m); };
  std::set<std::pair<std::string, BinKey>> failing_singles;  // (quantity, single bin)
  for (size_t k = 0; k < out.bins.size(); ++k) {
    BinMisfit& b = out.bins[k];
    b.p_bias = corrected(raw[k].bias);
    b.p_spread = corrected(raw[k].spread);
    b.p_detection = corrected(raw[k].detection);
    b.p_outliers = corrected(raw[k].outliers);
    const PairTests& pair = pair_tests[k];
    // Which of a pair's tests a quantity is (given_single's RawTests, field by field).
    const auto given = [](const RawTests& r, const std::string& q) {
      return q == "bias" ? r.bias : q == "spread" ? r.spread : q == "detection" ? r.detection : r.outliers;
    };
    const auto fail = [&](const char* quantity, double p, double measured, double predicted, double nats) {
      if (p >= alpha) return;
      const std::string q = quantity;
      if (b.region.size() == 1) {
        failing_singles.insert({q, pair.single[0]});
      }
      if (b.region.size() == 2) {
        for (size_t j = 0; j < 2; ++j) {
          // Explained by a failing single feature: the pair is that single's misfit at its share.
          if (failing_singles.count({q, pair.single[j]}) && corrected(given(pair.given[j], q)) >= alpha) return;
        }
      }
      const size_t count = q == "detection" ? b.pixels : q == "outliers" ? b.returns : b.inliers;
      FailingRegion f{quantity, b.region, measured, predicted, b.pixels, p, nats, nats / static_cast<double>(count),
                      ""};
      f.sentence = sentence(f, b);
      out.failing.push_back(std::move(f));
    };
    fail("bias", b.p_bias, b.bias_measured_m, b.bias_predicted_m, b.misfit_bias);
    fail("spread", b.p_spread, b.spread_measured_m, b.spread_predicted_m, b.misfit_spread);
    fail("detection", b.p_detection, b.detection_measured, b.detection_predicted, b.misfit_detection);
    fail("outliers", b.p_outliers, b.outliers_measured, b.outliers_predicted, b.misfit_outliers);
  }
  drop_explained_pairs(out.failing);
  std::stable_sort(out.failing.begin(), out.failing.end(), [](const FailingRegion& a, const FailingRegion& b) {
    return a.misfit_per_pixel > b.misfit_per_pixel;
  });
  return out;
}

}  // namespace lidartwin
