// Forward selection of the features an unexplained misfit follows (unexplained.h).
#include "lidartwin/analysis/unexplained.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>
#include <unordered_map>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "analysis/misfit_features.h"

namespace lidartwin {
namespace {

using analysis_detail::expected_outlier_share;
using analysis_detail::f64;
using analysis_detail::Feature;
using analysis_detail::Features;
using analysis_detail::inlier_z2;
using analysis_detail::kMinTested;
using analysis_detail::kOutlierZ;

constexpr int kMaxFeatures = 3;

const char* const kSearched[] = {"range",   "incidence", "reflectivity", "signal", "near_ir", "beam",
                                 "azimuth", "time",      "edge",         "retro",  "material"};

std::string words(const std::string& feature) {
  if (feature == "near_ir") return "near-IR";
  if (feature == "signal") return "expected signal";
  if (feature == "edge") return "distance to depth edges";
  if (feature == "retro") return "distance to retroreflectors";
  return feature;
}

// How a quantity's bins are tested. Bias: a weighted mean in metres (x = residual / sigma^2, v =
// 1 / sigma^2, so sum x / sum v is the inverse-variance mean and (x - v c)^2 / v its chi-square).
// Spread: each bin's variance of z about its own mean. Detection and outliers: Bernoulli counts,
// by the likelihood-ratio (G) statistic, since Pearson's overstates misses where the model is sure.
// A group's level is a factor on the model's detection rate, but a share added to its outlier rate
// (kRate): a missing effect's outliers (an edge partner's returns) come on top of the few the model
// expects, not in proportion to them. As a factor, the model's own outliers, at depth edges where
// E2's tails meet the weaker signal, made a common level fit edge bins holding every extra outlier.
enum class Kind { kBias, kSpread, kBernoulli, kRate };

Kind kind_of(const std::string& quantity) {
  return quantity == "bias"       ? Kind::kBias
         : quantity == "spread"   ? Kind::kSpread
         : quantity == "outliers" ? Kind::kRate
                                  : Kind::kBernoulli;
}
bool counts(Kind kind) { return kind == Kind::kBernoulli || kind == Kind::kRate; }

// One quantity's residual, pixel by pixel: x and v as Kind says; m and q what was measured and what
// the model predicts, in natural units (metres, 0/1 and probabilities), for the words.
struct Residual {
  Kind kind = Kind::kBias;
  std::vector<uint8_t> used;
  std::vector<float> x, v, m, q;
};

// A probability kept off 0 and 1 as the pixel likelihood keeps it (kImpossible), so the counts'
// statistics weigh a miss the model is sure of as the fits do.
double likelihood_floor(double p) { return std::clamp(p, kImpossible, 1.0 - kImpossible); }

// bias_shift_m: for the spread, each pixel's share of the unexplained bias (its cell's mean, in
// metres), taken out first so that a bias differing between pixels of one bin is not read as spread.
Residual residual_of(const std::string& quantity, const PixelTable& t, const PixelScores& s,
                     const std::vector<float>* bias_shift_m = nullptr) {
  const size_t n = t.size();
  Residual r{kind_of(quantity),     std::vector<uint8_t>(n, 0), std::vector<float>(n),
             std::vector<float>(n), std::vector<float>(n),      std::vector<float>(n)};
  const auto put = [&r](size_t i, double x, double v, double m, double q) {
    r.used[i] = 1;
    r.x[i] = static_cast<float>(x);
    r.v[i] = static_cast<float>(v);
    r.m[i] = static_cast<float>(m);
    r.q[i] = static_cast<float>(q);
  };
  const bool detection = quantity == "detection", outliers = quantity == "outliers", bias = quantity == "bias";
  for (size_t i = 0; i < n; ++i) {
    if (t.ideal_range_m[i] <= 0.0f) continue;
    const bool returned = t.range_m[i] > 0.0f;
    if (detection) {
      put(i, 0.0, 1.0, returned ? 1.0 : 0.0, likelihood_floor(f64(t.p_detect[i])));
      continue;
    }
    if (!returned) continue;
    const bool outlier = s.impossible[i] || std::abs(f64(s.z[i])) > kOutlierZ;
    if (outliers) {
      put(i, 0.0, 1.0, outlier ? 1.0 : 0.0, likelihood_floor(expected_outlier_share(t, i)));
      continue;
    }
    if (outlier) continue;
    const double sd = f64(s.sd_m[i]), step = f64(t.step_m[i]);
    // z's variance among inliers (more with E2's tails), with the range bins' (Sheppard).
    const double vz = inlier_z2(t, i) + step * step / (12.0 * sd * sd);
    const double e = f64(t.range_m[i]) - f64(s.mean_m[i]);
    if (bias) {
      const double ideal = f64(t.ideal_range_m[i]);
      put(i, e / (sd * sd), vz / (sd * sd), f64(t.range_m[i]) - ideal, f64(s.mean_m[i]) - ideal);
    } else {
      const double shift = bias_shift_m ? f64((*bias_shift_m)[i]) : 0.0;
      put(i, (e - shift) / sd, vz, e - shift, sd * sd * vz);
    }
  }
  return r;
}

// 2 [M ln(M/E) + (N - M) ln((N - M)/(N - E))]: M events in N where E were expected.
double g_statistic(double m, double e, double n) {
  e = std::clamp(e, 1e-9, n - 1e-9);
  const auto term = [](double a, double b) { return a > 0.0 ? a * std::log(a / b) : 0.0; };
  return 2.0 * (term(m, e) + term(n - m, n - e));
}

struct BinSums {
  double x = 0, xx = 0, v = 0, m = 0, mm = 0, q = 0;
  size_t n = 0;
  void add(const Residual& r, size_t i) {
    x += f64(r.x[i]);
    xx += f64(r.x[i]) * f64(r.x[i]);
    v += f64(r.v[i]);
    m += f64(r.m[i]);
    mm += f64(r.m[i]) * f64(r.m[i]);
    q += f64(r.q[i]);
    ++n;
  }
  bool tested() const { return n >= kMinTested && v > 0; }
  double count() const { return static_cast<double>(n); }
  // The Gaussian kinds' score and its variance if the model is true: the summed x, or for the
  // spread (n - 1) times the sample variance of z less its expectation (variance 2 (n - 1) vz^2).
  std::pair<double, double> score(Kind kind) const {
    if (kind != Kind::kSpread) return {x, v};
    const double vz = v / count();
    return {xx - x * x / count() - (count() - 1.0) * vz, 2.0 * (count() - 1.0) * vz * vz};
  }
  // How far the bin is from the model (chi-square, 1 dof), and from a model scaled to the level
  // `level` of its group (a shift in metres, a spread's extra variance, a factor on the rate).
  double against_model(Kind kind) const {
    if (counts(kind)) return g_statistic(m, q, count());
    const auto [sx, sv] = score(kind);
    return sx * sx / sv;
  }
  double against_level(Kind kind, double level) const {
    if (kind == Kind::kBernoulli) return g_statistic(m, std::min(level * q, count()), count());
    if (kind == Kind::kRate) return g_statistic(m, std::clamp(q + level * count(), 0.0, count()), count());
    const auto [sx, sv] = score(kind);
    const double d = sx - sv * level;
    return d * d / sv;
  }
  // The group level these sums give (see against_level).
  static double level_of(Kind kind, double sx, double sv, double sm, double sq, double n) {
    if (kind == Kind::kRate) return n > 0 ? (sm - sq) / n : 0.0;
    return kind == Kind::kBernoulli ? (sq > 0 ? sm / sq : 1.0) : (sv > 0 ? sx / sv : 0.0);
  }
  // Signed standard deviations from the model.
  double z(Kind kind) const {
    const double sign = counts(kind) ? (m >= q ? 1.0 : -1.0) : (score(kind).first >= 0 ? 1.0 : -1.0);
    return sign * std::sqrt(against_model(kind));
  }
  // Measured minus model in natural units (metres, fractions), or the spread's ratio less 1.
  double difference(Kind kind) const {
    if (kind != Kind::kSpread) return (m - q) / count();
    return std::sqrt(std::max(mm - m * m / count(), 0.0) / std::max(q * (count() - 1.0) / count(), 1e-300)) - 1.0;
  }
};

// Heterogeneity of the residual between the bins of `bins` within each group, each group taken at
// its own level: chi-square with (tested bins - 1) degrees of freedom per group. Bins of fewer than
// kMinTested pixels are left out.
struct Heterogeneity {
  double chi2 = 0, dof = 0;
};
Heterogeneity heterogeneity(const Residual& r, const std::vector<uint32_t>& group, uint32_t,
                            const std::vector<int16_t>& bins, int bin_count) {
  // Only the cells (group, bin) that hold pixels: refined groups times a feature's bins (beams)
  // are millions of cells, most of them empty, which a dense array cleared every call (seconds
  // per compare on the real OS-1-128's three frames). Sorted by cell, a group's bins are
  // contiguous and in bin order, so the sums are the dense array's, term for term.
  std::unordered_map<uint64_t, BinSums> cells;
  for (size_t i = 0; i < bins.size(); ++i) {
    if (!r.used[i] || bins[i] < 0 || group[i] == UINT32_MAX) continue;
    cells[static_cast<uint64_t>(group[i]) * static_cast<uint64_t>(bin_count) + static_cast<uint64_t>(bins[i])].add(r,
                                                                                                                   i);
  }
  std::vector<std::pair<uint64_t, const BinSums*>> tested_cells;
  tested_cells.reserve(cells.size());
  for (const auto& [cell, sums] : cells) {
    if (sums.tested()) tested_cells.emplace_back(cell, &sums);
  }
  std::sort(tested_cells.begin(), tested_cells.end());
  Heterogeneity h;
  const auto width = static_cast<uint64_t>(bin_count);
  for (size_t first = 0; first < tested_cells.size();) {
    size_t last = first;
    while (last < tested_cells.size() && tested_cells[last].first / width == tested_cells[first].first / width) ++last;
    double x = 0, v = 0, m = 0, q = 0, n = 0;
    for (size_t k = first; k < last; ++k) {
      const BinSums& b = *tested_cells[k].second;
      const auto [bx, bv] = b.score(r.kind);
      x += bx;
      v += bv;
      m += b.m;
      q += b.q;
      n += b.count();
    }
    const auto tested = static_cast<double>(last - first);
    if (tested >= 2) {
      const double level = BinSums::level_of(r.kind, x, v, m, q, n);
      for (size_t k = first; k < last; ++k) h.chi2 += tested_cells[k].second->against_level(r.kind, level);
      h.dof += tested - 1;
    }
    first = last;
  }
  return h;
}

// The groups refined by one more feature, renumbered densely; pixels outside its bins drop out.
uint32_t refine(std::vector<uint32_t>& group, const std::vector<int16_t>& bins) {
  std::unordered_map<uint64_t, uint32_t> ids;
  for (size_t i = 0; i < group.size(); ++i) {
    if (group[i] == UINT32_MAX) continue;
    if (bins[i] < 0) {
      group[i] = UINT32_MAX;
      continue;
    }
    const uint64_t key = (static_cast<uint64_t>(group[i]) << 16) | static_cast<uint16_t>(bins[i]);
    group[i] = ids.try_emplace(key, static_cast<uint32_t>(ids.size())).first->second;
  }
  return static_cast<uint32_t>(ids.size());
}

std::string signed_mm(double m) { return fmt::format("{:+.1f} mm", 1000.0 * m); }
std::string percent(double f) { return fmt::format("{:.1f} %", 100.0 * f); }

// The first feature's bins, described in natural units: its trend and its worst bins.
struct FirstFeature {
  std::string trend;  // "grows with", "falls with", "varies with"
  std::vector<std::string> regions;
  std::vector<std::string> phrases;
  double size = 0;
};
FirstFeature describe_first(const std::string& quantity, const Residual& r, const Feature& f,
                            const std::vector<int16_t>& bins) {
  std::vector<BinSums> acc(static_cast<size_t>(f.bins()));
  for (size_t i = 0; i < bins.size(); ++i) {
    if (r.used[i] && bins[i] >= 0) acc[static_cast<size_t>(bins[i])].add(r, i);
  }
  struct Tested {
    int k;
    double d, z;
  };
  std::vector<Tested> tested;
  for (int k = 0; k < f.bins(); ++k) {
    const BinSums& b = acc[static_cast<size_t>(k)];
    if (!b.tested()) continue;
    tested.push_back({k, b.difference(r.kind), b.z(r.kind)});
  }
  FirstFeature out;
  out.trend = "varies with";
  if (f.ordered && tested.size() >= 3) {
    const bool up = std::adjacent_find(tested.begin(), tested.end(),
                                       [](const Tested& a, const Tested& b) { return b.d < a.d; }) == tested.end();
    const bool down = std::adjacent_find(tested.begin(), tested.end(),
                                         [](const Tested& a, const Tested& b) { return b.d > a.d; }) == tested.end();
    if (up) out.trend = "grows with";
    if (down) out.trend = "falls with";
  }
  for (const Tested& b : tested) out.size = std::max(out.size, std::abs(b.d));
  std::vector<Tested> worst;
  std::copy_if(tested.begin(), tested.end(), std::back_inserter(worst), [](const Tested& b) {
    return std::abs(b.z) > 4.0;  // a bin that fails on its own
  });
  std::sort(worst.begin(), worst.end(), [](const Tested& a, const Tested& b) { return std::abs(a.d) > std::abs(b.d); });
  if (worst.size() > 3) worst.resize(3);
  for (const Tested& b : worst) {
    const BinSums& s = acc[static_cast<size_t>(b.k)];
    const auto n = static_cast<double>(s.n);
    const std::string where = describe({{f.name == "beam_group" ? std::string("beam") : f.name, f.range_of(b.k)}});
    out.regions.push_back(where);
    if (quantity == "bias") {
      out.phrases.push_back(
          fmt::format("{}: {} against the model's {}", where, signed_mm(s.m / n), signed_mm(s.q / n)));
    } else if (quantity == "spread") {
      out.phrases.push_back(fmt::format("{}: {:.2g} times the model's spread", where, b.d + 1.0));
    } else if (quantity == "detection") {
      out.phrases.push_back(
          fmt::format("{}: {} return against the model's {}", where, percent(s.m / n), percent(s.q / n)));
    } else {
      out.phrases.push_back(
          fmt::format("{}: {} outliers against the model's {}", where, percent(s.m / n), percent(s.q / n)));
    }
  }
  return out;
}

std::string listed(const std::vector<std::string>& names, const char* last_joint) {
  std::vector<std::string> w;
  for (const auto& n : names) w.push_back(words(n));
  if (w.size() <= 1) return w.empty() ? "" : w[0];
  return fmt::format("{} {} {}", fmt::join(w.begin(), w.end() - 1, ", "), last_joint, w.back());
}

// Every searched feature's bin of every pixel (-1: none, or the beam meets no surface).
using FeatureBins = std::map<std::string, std::vector<int16_t>>;
FeatureBins feature_bins(const PixelTable& t, const Features& features) {
  FeatureBins bins;
  for (const char* name : kSearched) {
    if (!features.has(name)) continue;
    const Feature& f = features[name];
    std::vector<int16_t>& b = bins[name];
    b.resize(t.size(), -1);
    for (size_t i = 0; i < t.size(); ++i) {
      if (t.ideal_range_m[i] > 0.0f) b[i] = static_cast<int16_t>(f.bin(f.value(i)));
    }
  }
  return bins;
}

// Each group's level (bias: its inverse-variance mean residual, metres), pixel by pixel (0 outside).
std::vector<float> group_levels(const Residual& r, const std::vector<uint32_t>& group, uint32_t groups) {
  std::vector<double> x(groups, 0.0), v(groups, 0.0);
  for (size_t i = 0; i < group.size(); ++i) {
    if (!r.used[i] || group[i] == UINT32_MAX) continue;
    x[group[i]] += f64(r.x[i]);
    v[group[i]] += f64(r.v[i]);
  }
  std::vector<float> out(group.size(), 0.0f);
  for (size_t i = 0; i < group.size(); ++i) {
    if (group[i] != UINT32_MAX && v[group[i]] > 0) out[i] = static_cast<float>(x[group[i]] / v[group[i]]);
  }
  return out;
}

struct Explained {
  std::optional<UnexplainedMisfit> misfit;  // none: nothing left to say (a spread the bias's pattern made)
  std::vector<uint32_t> group;              // each pixel's cell of the chosen features (UINT32_MAX: none)
  uint32_t groups = 1;
};

// bias_shift_m: for the spread (residual_of).
Explained explain(const std::string& quantity, const PixelTable& t, const PixelScores& s, const Misfit& misfit,
                  const Features& features, const FeatureBins& bins, double alpha,
                  const std::vector<float>* bias_shift_m = nullptr) {
  const Residual r = residual_of(quantity, t, s, bias_shift_m);
  Explained out;
  UnexplainedMisfit u;
  u.quantity = quantity;
  u.unit = quantity == "bias" ? "m" : quantity == "spread" ? "ratio" : "fraction";
  std::vector<std::string> remaining;
  for (const auto& [name, b] : bins) remaining.push_back(name);
  const auto tests_made = static_cast<double>(remaining.size() * kMaxFeatures);  // Bonferroni
  std::vector<uint32_t>& group = out.group;
  group.assign(t.size(), 0);
  uint32_t& groups = out.groups;
  std::vector<FeatureTest> last_round;
  for (int round = 0; round < kMaxFeatures && !remaining.empty(); ++round) {
    std::vector<FeatureTest> tests;
    for (const std::string& name : remaining) {
      const Feature& f = features[name];
      const Heterogeneity h = heterogeneity(r, group, groups, bins.at(name), f.bins());
      const double p = h.dof > 0 ? 1.0 - chi2_cdf(h.chi2, h.dof) : 1.0;
      tests.push_back({name, h.chi2, h.dof, std::min(1.0, p * tests_made)});
    }
    // The strongest: the largest excess over what chance gives (chi2 - dof), among the significant.
    std::optional<size_t> best;
    for (size_t k = 0; k < tests.size(); ++k) {
      if (tests[k].p_value >= alpha) continue;
      if (!best || tests[k].chi2 - tests[k].dof > tests[*best].chi2 - tests[*best].dof) best = k;
    }
    last_round = tests;
    if (!best) break;
    const std::string name = tests[*best].feature;
    u.features.push_back(name);
    u.tests.push_back(tests[*best]);
    groups = refine(group, bins.at(name));
    std::erase(remaining, name);
    last_round.clear();
    for (const FeatureTest& test : tests) {
      if (test.feature != name) last_round.push_back(test);
    }
  }
  // What it does not follow: the last round's tests, made within the chosen features' bins.
  for (const FeatureTest& test : last_round) {
    if (std::find(u.features.begin(), u.features.end(), test.feature) != u.features.end()) continue;
    u.tests.push_back(test);
    if (test.p_value >= alpha && test.dof > 0) u.not_features.push_back(test.feature);  // dof 0: not testable
  }
  const std::string what = quantity == "bias"        ? "The unexplained range bias"
                           : quantity == "spread"    ? "The unexplained range spread"
                           : quantity == "detection" ? "The unexplained detection rate"
                                                     : "The unexplained outlier rate";
  if (u.features.empty()) {
    BinSums all;
    for (size_t i = 0; i < t.size(); ++i) {
      if (r.used[i]) all.add(r, i);
    }
    const double d = all.difference(r.kind);
    const auto count = static_cast<double>(std::max<size_t>(all.n, 1));
    if (all.tested() && 1.0 - chi2_cdf(all.against_model(r.kind), 1.0) < alpha) {  // a level, alike in every bin
      u.size = std::abs(d);
      const std::string level =
          quantity == "bias"
              ? fmt::format("{} against the model's {}", signed_mm(all.m / count), signed_mm(all.q / count))
          : quantity == "spread"
              ? fmt::format("{:.2g} times the model's spread", d + 1.0)
              : fmt::format("{} against the model's {}", percent(all.m / count), percent(all.q / count));
      u.sentence =
          fmt::format("{} is alike everywhere ({}): it follows none of {}.", what, level, listed(u.not_features, "or"));
      out.misfit = std::move(u);
      return out;
    }
    // The spread failed only where the unexplained bias differs within a bin: said with the bias.
    if (bias_shift_m) return out;
    // Neither a level nor a trend across the capture: confined to the worst failing region(s),
    // too few pixels to move a whole feature's bins.
    const auto worst = std::find_if(misfit.failing.begin(), misfit.failing.end(),
                                    [&](const FailingRegion& f) { return f.quantity == quantity; });
    if (worst == misfit.failing.end()) return out;
    u.not_features.clear();
    for (const auto& [name, range] : worst->region) u.features.push_back(name);
    u.regions.push_back(describe(worst->region));
    u.size = std::abs(worst->measured - worst->predicted);
    u.sentence = fmt::format("{} is confined to a small region ({}); across the capture it follows no feature.", what,
                             worst->sentence);
    out.misfit = std::move(u);
    return out;
  }
  const FirstFeature first = describe_first(quantity, r, features[u.features.front()], bins.at(u.features.front()));
  u.size = first.size;
  u.regions = first.regions;
  std::string sentence = fmt::format("{} {} {}", what, first.trend, words(u.features.front()));
  if (u.features.size() > 1) {
    sentence += fmt::format(", and within its bins with {}",
                            listed(std::vector<std::string>(u.features.begin() + 1, u.features.end()), "and"));
  }
  if (!first.phrases.empty()) sentence += fmt::format(" ({})", fmt::join(first.phrases, "; "));
  if (!u.not_features.empty()) sentence += fmt::format("; it does not depend on {}", listed(u.not_features, "or"));
  u.sentence = sentence + ".";
  out.misfit = std::move(u);
  return out;
}

}  // namespace

std::vector<UnexplainedMisfit> explain_misfit(const PixelTable& table, const PixelScores& scores, const Misfit& misfit,
                                              double alpha) {
  std::set<std::string> failing;
  for (const FailingRegion& f : misfit.failing) failing.insert(f.quantity);
  std::vector<UnexplainedMisfit> out;
  if (failing.empty()) return out;
  const Features features = analysis_detail::make_features(table);
  const FeatureBins bins = feature_bins(table, features);
  // The bias first: its pattern, taken out of z, is what the spread is judged against.
  std::optional<std::vector<float>> bias_shift;
  if (failing.count("bias")) {
    Explained bias = explain("bias", table, scores, misfit, features, bins, alpha);
    if (bias.misfit && !bias.misfit->features.empty()) {
      bias_shift = group_levels(residual_of("bias", table, scores), bias.group, bias.groups);
    }
    if (bias.misfit) out.push_back(std::move(*bias.misfit));
  }
  for (const char* quantity : {"spread", "detection", "outliers"}) {
    if (!failing.count(quantity)) continue;
    const std::vector<float>* shift = std::string(quantity) == "spread" && bias_shift ? &*bias_shift : nullptr;
    Explained e = explain(quantity, table, scores, misfit, features, bins, alpha, shift);
    if (e.misfit) out.push_back(std::move(*e.misfit));
  }
  return out;
}

FeaturePattern strongest_pattern(const PixelTable& table, const PixelScores& scores) {
  const Features features = analysis_detail::make_features(table);
  const FeatureBins bins = feature_bins(table, features);
  FeaturePattern best;
  double best_bic = 0.0;
  for (const char* quantity : {"bias", "spread", "detection", "outliers"}) {
    const Residual r = residual_of(quantity, table, scores);
    const auto used = static_cast<double>(std::count(r.used.begin(), r.used.end(), uint8_t{1}));
    for (const auto& [name, b] : bins) {
      std::vector<BinSums> acc(static_cast<size_t>(features[name].bins()));
      for (size_t i = 0; i < b.size(); ++i) {
        if (r.used[i] && b[i] >= 0) acc[static_cast<size_t>(b[i])].add(r, i);
      }
      double chi2 = 0.0, dof = 0.0;
      for (const BinSums& bin : acc) {
        if (!bin.tested()) continue;
        chi2 += bin.against_model(r.kind);
        dof += 1.0;
      }
      const double bic = chi2 - dof * std::log(std::max(used, 2.0));
      if (bic > best_bic) {
        best_bic = bic;
        best = {quantity, name, chi2, dof, static_cast<size_t>(used)};
      }
    }
  }
  return best;
}

PatternAdjustment pattern_adjustment(const PixelTable& table, const PixelScores& scores,
                                     const FeaturePattern& pattern) {
  PatternAdjustment out;
  out.quantity = pattern.quantity;
  out.target = pattern.quantity == "bias"        ? PatternAdjustment::Target::kBias
               : pattern.quantity == "spread"    ? PatternAdjustment::Target::kSpread
               : pattern.quantity == "detection" ? PatternAdjustment::Target::kDetection
                                                 : PatternAdjustment::Target::kOutliers;
  if (pattern.quantity.empty()) return out;
  const Features features = analysis_detail::make_features(table);
  const Feature& f = features[pattern.feature];
  const Residual r = residual_of(pattern.quantity, table, scores);
  out.bin.assign(table.size(), -1);
  std::vector<BinSums> acc(static_cast<size_t>(f.bins()));
  for (size_t i = 0; i < table.size(); ++i) {
    if (table.ideal_range_m[i] <= 0.0f) continue;
    const int k = f.bin(f.value(i));
    if (k < 0) continue;
    out.bin[i] = static_cast<int16_t>(k);
    if (r.used[i]) acc[static_cast<size_t>(k)].add(r, i);
  }
  const bool additive = r.kind == Kind::kBias || pattern.quantity == "outliers";
  out.value.assign(acc.size(), additive ? 0.0 : 1.0);
  for (size_t k = 0; k < acc.size(); ++k) {
    const BinSums& b = acc[k];
    if (!b.tested()) continue;
    if (r.kind == Kind::kBias) {
      out.value[k] = b.x / b.v;
    } else if (r.kind == Kind::kSpread) {
      const double vz = b.v / b.count();
      out.value[k] = std::clamp((b.xx - b.x * b.x / b.count()) / ((b.count() - 1.0) * vz), 0.05, 100.0);
    } else if (pattern.quantity == "detection") {
      out.value[k] = b.q > 0 ? b.m / b.q : 1.0;
    } else {
      out.value[k] = (b.m - b.q) / b.count();
    }
  }
  return out;
}

void PatternAdjustment::apply(size_t pixel, Prediction& p) const {
  const int16_t k = bin[pixel];
  if (k < 0) return;
  const double v = value[static_cast<size_t>(k)];
  switch (target) {
    case Target::kBias:  // measured against the reference, whatever it is: none of it is shared
      p.bias_m += v;
      p.unshared_bias_m += v;
      break;
    case Target::kSpread: p.variance_m2 *= v; break;
    case Target::kDetection: p.p_detect = std::min(p.p_detect * v, 1.0); break;
    case Target::kOutliers: p.outlier_mix = std::clamp(p.outlier_mix + v, 0.0, 1.0); break;
  }
}

void find_causes(const PixelTable& table, const PixelScores& scores, Misfit& misfit, double alpha) {
  misfit.causes.clear();
  if (misfit.failing.empty()) return;
  for (const UnexplainedMisfit& u : explain_misfit(table, scores, misfit, alpha)) {
    if (u.features.empty()) continue;
    misfit.causes.push_back({u.quantity, u.features, u.not_features});
  }
}

}  // namespace lidartwin
