// The failing regions merged into runs and ranked by the misfit they explain, those that localize
// it first (compare_report.h):
// what the terminal and report.html list, where report.json's "failing" keeps every bin.
#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/format.h>

#include "lidartwin/analysis/compare_report.h"

namespace lidartwin {
namespace {

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
// Digits where they tell rates apart: near 0 (outliers) and near 1 (detection).
std::string percent(double f) {
  if (f < 0.001) return fmt::format("{:.3f} %", 100 * f);
  if (f < 0.1) return fmt::format("{:.1f} %", 100 * f);
  if (f > 0.99 && f < 1.0) return fmt::format("{:.2f} %", std::min(100 * f, 99.99));  // not 1 unless 1
  return fmt::format("{:.0f} %", 100 * f);
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

// A run of several bins in words, with the spread of their values.
std::string run_sentence(const std::vector<const FailingRegion*>& bins, const std::string& place, size_t pixels) {
  const std::string q = bins.front()->quantity;
  std::vector<double> measured, predicted, ratio;
  for (const FailingRegion* f : bins) {
    measured.push_back(f->measured);
    predicted.push_back(f->predicted);
    ratio.push_back(q == "bias" ? f->measured - f->predicted : f->predicted > 0 ? f->measured / f->predicted : 0.0);
  }
  const auto [rlo, rhi] = std::minmax_element(ratio.begin(), ratio.end());
  const auto [mlo, mhi] = std::minmax_element(measured.begin(), measured.end());
  const auto [plo, phi] = std::minmax_element(predicted.begin(), predicted.end());
  const std::string count = fmt::format("{} bins, {} pixels", bins.size(), pixels);
  if (q == "bias") {
    return fmt::format("{}: the measured range is {} {} than the model's ({})", place, span(*rlo, *rhi, millimetres),
                       *rlo > 0 ? "longer" : "shorter", count);
  }
  if (q == "spread") {
    return fmt::format("{}: the measured spread is {} times the model's ({})", place,
                       span(*rlo, *rhi, [](double v) { return fmt::format("{:.2g}", v); }), count);
  }
  const std::string of = q == "detection" ? "of pixels return" : "of returns lie beyond 5 sigma";
  return fmt::format("{}: {} {}, the model expects {} ({})", place, span(*mlo, *mhi, percent), of,
                     span(*plo, *phi, percent), count);
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
  run.sentence = run_sentence(bins, run.where, run.pixels);
  return run;
}

}  // namespace

std::vector<FailingRun> failing_runs(const Misfit& misfit, const std::vector<std::string>& material_names) {
  // Single-feature regions by quantity, feature and lower edge; pairs stay as they are.
  std::vector<const FailingRegion*> single;
  std::vector<FailingRun> runs;
  for (const FailingRegion& f : misfit.failing) {
    if (f.region.size() == 1) single.push_back(&f);
    else runs.push_back(make_run({&f}, material_names));
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
      runs.push_back(make_run(current, material_names));
      current.clear();
    }
    current.push_back(f);
  }
  if (!current.empty()) runs.push_back(make_run(current, material_names));
  // A run over most of its feature's pixels ("incidence above 0°", every bin failing and merged)
  // carries the whole capture's misfit but says nothing of where it is: such runs come after those
  // that localize it, each group by the misfit it explains.
  std::map<std::string, size_t> feature_pixels;  // what each single feature bins, over its bins
  for (const BinMisfit& b : misfit.bins) {
    if (b.region.size() == 1) feature_pixels[b.region.front().first] += b.pixels;
  }
  const auto localizes = [&](const FailingRun& run) {
    if (run.region.size() != 1) return true;
    const auto all = feature_pixels.find(run.region.front().first);
    return all == feature_pixels.end() || 2 * run.pixels <= all->second;
  };
  std::stable_sort(runs.begin(), runs.end(), [&](const FailingRun& a, const FailingRun& b) {
    const bool la = localizes(a), lb = localizes(b);
    return la != lb ? la : a.misfit_nats > b.misfit_nats;
  });
  return runs;
}

}  // namespace lidartwin
