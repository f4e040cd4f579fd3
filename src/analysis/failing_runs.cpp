// The failing regions merged into runs and ranked by the misfit that sets them apart from the rest
// of their feature, those that localize it first (compare_report.h): what the terminal and
// report.html list, where report.json's "failing" keeps every bin.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/format.h>

#include "analysis/percent_text.h"
#include "lidartwin/analysis/compare_report.h"

namespace lidartwin {
namespace {

using analysis_detail::percent;

// Features whose bins are integers ([k, k] or [lo, hi] inclusive): neighbours when the next starts
// one after this one ends. Materials are ids, not an order: never merged.
bool integer_feature(const std::string& name) { return name == "beam" || name == "edge" || name == "retro"; }

bool neighbours(const FailingRegion& a, const FailingRegion& b) {
  const auto& [name, ra] = a.region.front();
  const auto& rb = b.region.front().second;
  if (name == "material") return false;
  return integer_feature(name) ? rb[0] == ra[1] + 1 : rb[0] == ra[1];
}

// The way a bin fails: above or below the model.
int direction(const FailingRegion& f) { return f.measured > f.predicted ? 1 : -1; }

std::string millimetres(double m) {
  const double mm = 1000.0 * std::abs(m);
  return mm < 10.0 ? fmt::format("{:.1f} mm", mm) : fmt::format("{:.0f} mm", mm);
}

// "3.1–5.2 mm", or one value when the run's bins agree to the digits shown.
template <typename Format>
std::string span(double lo, double hi, Format format) {
  std::string a = format(std::min(lo, hi));
  const std::string b = format(std::max(lo, hi));
  if (a == b) return a;
  const size_t unit = a.rfind(' ');
  if (unit != std::string::npos && b.ends_with(a.substr(unit))) a.resize(unit);
  return a + "–" + b;
}

// "material wall_grey (48)" where the scene names material 48.
std::string where(const Region& region, const std::vector<std::string>& names) {
  std::string text = describe(region);
  for (const auto& [name, range] : region) {
    const auto id = static_cast<size_t>(range[0]);
    if (name != "material" || id >= names.size() || names[id].empty()) continue;
    const std::string plain = fmt::format("material {}", id);
    const size_t at = text.find(plain);
    if (at != std::string::npos) text.replace(at, plain.size(), fmt::format("material {} ({})", names[id], id));
  }
  return text;
}

// A run's bins in feature order, as the quantity reads: the bias difference, the spread ratio, or
// the measured rate.
std::vector<double> values(const std::vector<const FailingRegion*>& bins) {
  std::vector<double> v;
  for (const FailingRegion* f : bins) {
    const std::string& q = f->quantity;
    v.push_back(q == "bias"     ? f->measured - f->predicted
                : q == "spread" ? (f->predicted > 0 ? f->measured / f->predicted : 0.0)
                                : f->measured);
  }
  return v;
}

std::string ratio_text(double v) { return v < 10.0 ? fmt::format("{:.1f} times", v) : fmt::format("{:.0f} times", v); }

// A feature as "rising with ..." names it.
std::string feature_noun(const std::string& feature) {
  if (feature == "signal") return "the expected signal";
  if (feature == "near_ir") return "the expected near-IR";
  if (feature == "edge") return "the distance to a depth edge";
  if (feature == "retro") return "the distance to a retroreflector";
  return feature;
}

// A run whose ends differ by half again or more, and hold its smallest and largest misfit, says how
// the misfit changes along the feature ("falling with time from 21 mm at time 0.00–0.40 s to 0.8
// mm at time 1.60–2.00 s"): the cause's signature (lidar-physics.md's diagnostic matrix), where a
// span of values would hide which end is which. One that peaks inside says where.
struct Trend {
  std::string way;     // "falling with time", "most at range 13–20 m"
  std::string detail;  // the way with its values
};
std::optional<Trend> trend(const std::vector<const FailingRegion*>& bins) {
  if (bins.size() < 3) return std::nullopt;
  const std::vector<double> v = values(bins);
  const std::string& q = bins.front()->quantity;
  std::vector<double> excess;
  for (const double x : v) excess.push_back(q == "spread" ? std::abs(x - 1.0) : std::abs(x));
  const auto text = [&](double x) { return q == "bias" ? millimetres(x) : q == "spread" ? ratio_text(x) : percent(x); };
  const auto peak = std::max_element(excess.begin(), excess.end()) - excess.begin();
  const auto low = std::min_element(excess.begin(), excess.end()) - excess.begin();
  const auto last = static_cast<std::ptrdiff_t>(bins.size()) - 1;
  if (peak != 0 && peak != last) {
    // Inside: said only when it stands out from both ends (not 7.5 mm among 7.2-7.4 mm).
    if (excess[static_cast<size_t>(peak)] < 1.5 * std::max(excess.front(), excess.back())) return std::nullopt;
    const std::string at = "most at " + describe(bins[static_cast<size_t>(peak)]->region);
    return Trend{at, fmt::format("{} ({})", at, text(v[static_cast<size_t>(peak)]))};
  }
  if ((low != 0 && low != last) || excess[static_cast<size_t>(peak)] < 1.5 * excess[static_cast<size_t>(low)]) {
    return std::nullopt;
  }
  // Rising or falling as the values shown read (millimetres of bias unsigned): a spread ratio whose
  // misfit grows from 0.7 to 0.4 times the model's falls.
  const bool rising = q == "bias" ? std::abs(v.back()) > std::abs(v.front()) : v.back() > v.front();
  const std::string way =
      fmt::format("{} with {}", rising ? "rising" : "falling", feature_noun(bins.front()->region.front().first));
  return Trend{way, fmt::format("{} from {} at {} to {} at {}", way, text(v.front()), describe(bins.front()->region),
                                text(v.back()), describe(bins.back()->region))};
}

// A run of several bins in words, with the spread of their values (or their trend).
std::string run_sentence(const std::vector<const FailingRegion*>& bins, const std::string& place, size_t pixels,
                         const std::optional<Trend>& found) {
  const std::string q = bins.front()->quantity;
  std::vector<double> measured, predicted;
  for (const FailingRegion* f : bins) {
    measured.push_back(f->measured);
    predicted.push_back(f->predicted);
  }
  const std::vector<double> ratio = values(bins);
  const auto [rlo, rhi] = std::minmax_element(ratio.begin(), ratio.end());
  const auto [mlo, mhi] = std::minmax_element(measured.begin(), measured.end());
  const auto [plo, phi] = std::minmax_element(predicted.begin(), predicted.end());
  const std::string count = fmt::format("{} bins, {} pixels", bins.size(), pixels);
  const std::optional<std::string> changes = found ? std::optional<std::string>(found->detail) : std::nullopt;
  if (q == "bias") {
    const std::string way = *rlo > 0 ? "longer" : "shorter";
    const std::string by = span(*rlo, *rhi, millimetres);
    if (changes)
      return fmt::format("{}: the measured range is {} {} than the model's, {} ({})", place, by, way, *changes, count);
    return fmt::format("{}: the measured range is {} {} than the model's ({})", place, by, way, count);
  }
  const std::string of = q == "spread" ? "" : q == "detection" ? " of pixels return" : " of returns lie beyond 5 sigma";
  const std::string model = q == "spread" ? "the model's" : "the model expects " + span(*plo, *phi, percent);
  const std::string what =
      q == "spread" ? "the measured spread is " + span(*rlo, *rhi, ratio_text) : span(*mlo, *mhi, percent) + of;
  if (changes)
    return fmt::format("{}: {}{}, {} ({})", place, what, q == "spread" ? " " + model : ", " + model, *changes, count);
  return fmt::format("{}: {}{} ({})", place, what, q == "spread" ? " " + model : ", " + model, count);
}

FailingRun make_run(const std::vector<const FailingRegion*>& bins, const std::vector<std::string>& names) {
  FailingRun run;
  const FailingRegion& first = *bins.front();
  run.quantity = first.quantity;
  run.region = first.region;
  run.bins = bins.size();
  for (const FailingRegion* f : bins) {
    run.pixels += f->pixels;
    run.misfit_nats += f->misfit_nats;
    run.p_value = std::min(run.p_value, f->p_value);
  }
  if (bins.size() == 1) {
    // The bin's own sentence, with the scene's name for a material.
    const std::string plain = describe(first.region);
    run.where = where(first.region, names);
    run.sentence = first.sentence;
    if (run.sentence.rfind(plain, 0) == 0) run.sentence.replace(0, plain.size(), run.where);
    return run;
  }
  run.region.front().second[1] = bins.back()->region.front().second[1];
  run.where = where(run.region, names);
  const std::optional<Trend> found = trend(bins);
  run.sentence = run_sentence(bins, run.where, run.pixels, found);
  if (found) run.trend = found->way;
  return run;
}

// A bin's misfit in one quantity as a signed deviation per pixel: s = ±sqrt(2 KL / n), so that
// n s^2 / 2 is the bin's misfit (nats) and bins failing the same way have the same sign.
struct Deviation {
  double n = 0.0, s = 0.0;
};
Deviation deviation(const BinMisfit& b, const std::string& quantity) {
  double nats = 0.0, n = 0.0;
  bool above = false;
  if (quantity == "bias") {
    nats = b.misfit_bias, n = static_cast<double>(b.inliers), above = b.bias_measured_m > b.bias_predicted_m;
  } else if (quantity == "spread") {
    nats = b.misfit_spread, n = static_cast<double>(b.inliers), above = b.spread_ratio > 1.0;
  } else if (quantity == "detection") {
    nats = b.misfit_detection, n = static_cast<double>(b.pixels), above = b.detection_measured > b.detection_predicted;
  } else {
    nats = b.misfit_outliers, n = static_cast<double>(b.returns), above = b.outliers_measured > b.outliers_predicted;
  }
  if (n <= 0.0) return {};
  const double s = std::sqrt(2.0 * std::max(nats, 0.0) / n);
  return {n, above ? s : -s};
}

// Which binning a region belongs to: its features' names ("range", "range+incidence").
std::string binning(const Region& region) {
  std::string key;
  for (const auto& [name, range] : region) key += (key.empty() ? "" : "+") + name;
  return key;
}

// How much of a run's misfit its feature explains: its bins' misfit about the deviation the whole
// binning shows on average (sum n (s - mean s)^2 / 2). A hidden warm-up drift makes every material
// 7 mm long alike: those runs carry much misfit but explain none of it (each material is as wrong as
// the rest), where the first time bins, 15 mm long against 1 mm later, do. Bins that fail no
// differently from the rest of their binning thus come after those that say where the misfit is.
class Contrast {
 public:
  explicit Contrast(const Misfit& misfit) {
    for (const BinMisfit& b : misfit.bins) {
      for (const char* q : {"bias", "spread", "detection", "outliers"}) {
        const Deviation d = deviation(b, q);
        Pool& pool = pools_[std::string(q) + ":" + binning(b.region)];
        pool.n += d.n;
        pool.ns += d.n * d.s;
        bins_[std::string(q) + ":" + describe(b.region)] = d;
      }
    }
  }
  // The run's bins (one region, or a merged run's regions).
  double localized_nats(const std::vector<const FailingRegion*>& regions) const {
    double nats = 0.0;
    for (const FailingRegion* f : regions) {
      const auto bin = bins_.find(f->quantity + ":" + describe(f->region));
      const auto pool = pools_.find(f->quantity + ":" + binning(f->region));
      if (bin == bins_.end() || pool == pools_.end() || pool->second.n <= 0.0) continue;
      const double mean = pool->second.ns / pool->second.n;
      nats += 0.5 * bin->second.n * (bin->second.s - mean) * (bin->second.s - mean);
    }
    return nats;
  }

 private:
  struct Pool {
    double n = 0.0, ns = 0.0;
  };
  std::map<std::string, Pool> pools_;
  std::map<std::string, Deviation> bins_;
};

// Each feature's tested bins (each alone, at least kMinTested pixels): their spans.
using TestedBins = std::map<std::string, std::vector<std::array<double, 2>>>;
TestedBins tested_bins(const Misfit& misfit) {
  constexpr size_t kMinTested = 30;
  TestedBins bins;
  for (const BinMisfit& b : misfit.bins) {
    if (b.region.size() != 1 || b.pixels < kMinTested) continue;
    bins[b.region.front().first].push_back(b.region.front().second);
  }
  return bins;
}

// A run over (nearly) every tested bin of its feature names no place ("incidence above 0°",
// "azimuth 0–360°", "beams 2–125" of 128): it says the misfit is everywhere along that feature,
// and is named so. One whose misfit changes along it (a trend: "falling with time") names its
// cause by the trend, and keeps its span.
constexpr double kEverywhereShare = 0.9;
void name_everywhere(FailingRun& run, const TestedBins& tested) {
  if (run.region.size() != 1 || run.bins < 2 || !run.trend.empty()) return;
  const auto& [name, range] = run.region.front();
  const auto bins = tested.find(name);
  if (bins == tested.end()) return;
  const auto inside = std::ranges::count_if(
      bins->second, [&range](const std::array<double, 2>& b) { return b[0] >= range[0] && b[1] <= range[1]; });
  if (static_cast<double>(inside) < kEverywhereShare * static_cast<double>(bins->second.size())) return;
  const std::string everywhere = "everywhere (" + run.where + ")";
  if (run.sentence.rfind(run.where, 0) == 0) run.sentence.replace(0, run.where.size(), everywhere);
  run.where = everywhere;
  run.everywhere = true;
}

}  // namespace

std::vector<FailingRun> failing_runs(const Misfit& misfit, const std::vector<std::string>& material_names) {
  // Single-feature regions by quantity, feature and lower edge; pairs stay as they are.
  const Contrast contrast(misfit);
  std::vector<const FailingRegion*> single;
  std::vector<FailingRun> runs;
  const TestedBins tested = tested_bins(misfit);
  const auto add = [&](const std::vector<const FailingRegion*>& bins) {
    runs.push_back(make_run(bins, material_names));
    runs.back().localized_nats = contrast.localized_nats(bins);
    name_everywhere(runs.back(), tested);
  };
  for (const FailingRegion& f : misfit.failing) {
    if (f.region.size() == 1) single.push_back(&f);
    else add({&f});
  }
  std::sort(single.begin(), single.end(), [](const FailingRegion* a, const FailingRegion* b) {
    return std::tie(a->quantity, a->region.front().first, a->region.front().second[0]) <
           std::tie(b->quantity, b->region.front().first, b->region.front().second[0]);
  });
  std::vector<const FailingRegion*> current;
  for (const FailingRegion* f : single) {
    const bool joins = !current.empty() && current.back()->quantity == f->quantity &&
                       current.back()->region.front().first == f->region.front().first &&
                       neighbours(*current.back(), *f) && direction(*current.back()) == direction(*f);
    if (!joins && !current.empty()) {
      add(current);
      current.clear();
    }
    current.push_back(f);
  }
  if (!current.empty()) add(current);
  // Where the quantity's cause is known (misfit.causes), a run of a feature it follows leads, in
  // the order they are followed; one of a feature that only rides along with them comes last and
  // says so. The rest, and every pair region, keep their place between, by the misfit they
  // localize.
  const auto cause_of = [&misfit](const std::string& quantity) -> const MisfitCause* {
    for (const MisfitCause& c : misfit.causes) {
      if (c.quantity == quantity) return &c;
    }
    return nullptr;
  };
  const auto position = [](const std::vector<std::string>& list, const std::string& name) {
    return static_cast<size_t>(std::find(list.begin(), list.end(), name) - list.begin());
  };
  std::vector<int> tier(runs.size(), 1);
  std::vector<size_t> order(runs.size(), 0);
  for (size_t k = 0; k < runs.size(); ++k) {
    FailingRun& run = runs[k];
    const MisfitCause* cause = cause_of(run.quantity);
    if (cause == nullptr || run.region.size() != 1) continue;
    const std::string& feature = run.region.front().first;
    if (const size_t at = position(cause->follows, feature); at < cause->follows.size()) {
      tier[k] = 0;
      order[k] = at;
    } else if (position(cause->rides_along, feature) < cause->rides_along.size()) {
      tier[k] = 2;
      run.rides_along = cause->follows.front();
      run.sentence += fmt::format(" (rides along with {}: within its bins, this feature fails no more)",
                                  feature_noun(cause->follows.front()));
    }
  }
  std::vector<size_t> index(runs.size());
  for (size_t k = 0; k < runs.size(); ++k) index[k] = k;
  std::stable_sort(index.begin(), index.end(), [&](size_t a, size_t b) {
    if (tier[a] != tier[b]) return tier[a] < tier[b];
    if (tier[a] == 0 && order[a] != order[b]) return order[a] < order[b];
    const FailingRun &x = runs[a], &y = runs[b];
    return x.localized_nats != y.localized_nats ? x.localized_nats > y.localized_nats : x.misfit_nats > y.misfit_nats;
  });
  std::vector<FailingRun> ranked;
  ranked.reserve(runs.size());
  for (const size_t k : index) ranked.push_back(std::move(runs[k]));
  return ranked;
}

}  // namespace lidartwin
