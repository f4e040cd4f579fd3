// The report's first sentence (report.json's "verdict_sentence"): what is wrong, in words, and what
// to do next. The terminal and report.html both lead with it.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "lidartwin/analysis/compare_report.h"

namespace lidartwin {
namespace {

std::string joined(const std::vector<std::string>& parts, const char* last = " and ") {
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) out += (i == 0 ? "" : i + 1 == parts.size() ? last : ", ") + parts[i];
  return out;
}

std::string quantity_words(const std::string& quantity) {
  if (quantity == "bias") return "the range bias";
  if (quantity == "spread") return "the spread";
  return quantity;  // detection, outliers
}

// The two quantities that carry most of the failing misfit (nats over their failing regions), each
// with its first run (failing_runs' order) and how it changes: "the range bias (worst: time 0.00–2.00 s,
// falling with time)".
std::string where_it_fails(const CompareResult& result) {
  std::map<std::string, double> total;
  std::map<std::string, const FailingRun*> worst;
  const std::vector<FailingRun> runs = failing_runs(result.misfit, result.inputs.material_names);
  for (const FailingRun& run : runs) {  // largest first
    total[run.quantity] += run.misfit_nats;
    if (worst[run.quantity] == nullptr) worst[run.quantity] = &run;
  }
  std::vector<std::string> quantities;
  for (const auto& [quantity, nats] : total) quantities.push_back(quantity);
  std::sort(quantities.begin(), quantities.end(),
            [&](const std::string& a, const std::string& b) { return total[a] > total[b]; });
  quantities.resize(std::min<size_t>(quantities.size(), 2));
  std::vector<std::string> parts;
  for (const std::string& q : quantities) {
    const FailingRun& run = *worst[q];
    parts.push_back(
        fmt::format("{} (worst: {}{})", quantity_words(q), run.where, run.trend.empty() ? "" : ", " + run.trend));
  }
  return joined(parts);
}

// What the diagnosis found, as a clause: "--diagnose says dropout (E5) is missing".
std::string diagnosis_words(const Diagnosis& d) {
  std::vector<std::string> found;
  std::vector<std::string> missing;
  for (const Candidate& c : d.selected) missing.push_back(fmt::format("{} ({})", c.effect, c.catalogue));
  if (!missing.empty()) found.push_back(joined(missing) + (missing.size() == 1 ? " is missing" : " are missing"));
  for (const Replacement& r : d.replace) {
    found.push_back(fmt::format("{} ({}) has the wrong form and {} ({}) fits in its place", r.effect, r.catalogue,
                                r.with.effect, r.with.catalogue));
  }
  if (!found.empty()) return "--diagnose says " + joined(found);
  if (!d.unexplained.empty()) {
    const UnexplainedMisfit& u = d.unexplained.front();
    return fmt::format("--diagnose finds no library effect that explains it ({} follows {})",
                       quantity_words(u.quantity), u.features.empty() ? std::string("no feature") : joined(u.features));
  }
  std::vector<std::string> refitted;
  for (const ParameterMisfit& m : d.parameter_misfit) refitted.push_back(m.refit.effect);
  if (!refitted.empty()) return "--diagnose adds no effect but refits the profile's " + joined(refitted);
  return "--diagnose finds no library effect missing";
}

}  // namespace

std::string unit_spread_words(const CompareResult& result) {
  const Misfit& misfit = result.misfit;
  // Over all returns: the range bins hold every inlier once; their ratios' inlier-weighted RMS.
  double ratio2 = 0.0, inliers = 0.0;
  size_t tighter = 0, failing = 0;
  double lo = 1e300, hi = 0.0;
  for (const BinMisfit& b : misfit.bins) {
    if (b.region.size() == 1 && b.region[0].first == "range" && b.inliers > 0) {
      ratio2 += static_cast<double>(b.inliers) * b.spread_ratio * b.spread_ratio;
      inliers += static_cast<double>(b.inliers);
    }
    if (b.p_spread < result.alpha) {
      ++failing;
      tighter += b.spread_ratio < 1.0;
      lo = std::min(lo, b.spread_ratio);
      hi = std::max(hi, b.spread_ratio);
    }
  }
  if (inliers <= 0.0 || failing == 0) return "";
  // Tighter only: a spread wider than the model's nearly everywhere is as often an effect the
  // profile lacks (E2's tails inside 5 sigma, E4's footprint), which the diagnosis names; no missing
  // effect makes a unit tighter than the profile everywhere.
  const double all = std::sqrt(ratio2 / inliers);
  if (all >= 1.0 / 1.15 || tighter < 9 * failing / 10) return "";
  const std::string line = result.prod_line.empty() ? std::string("this product") : "the " + result.prod_line;
  std::string out = fmt::format(
      "this unit's range noise is tighter than the profile's: its spread is {:.2f} of the model's over all returns "
      "({:.2f}–{:.2f} in the {} bins where the spread fails)",
      all, lo, hi, failing);
  if (result.unit_range_spread > 0.0) {
    const bool within = all >= 1.0 / result.unit_range_spread * 0.999;
    out += fmt::format(", {} the {:.2g}x by which units of {} are known to differ (the profile's unit_to_unit)",
                       within ? "within" : "beyond", result.unit_range_spread, line);
  } else {
    out += fmt::format(", and the profile does not say how far units of {} differ", line);
  }
  return out;
}

std::string verdict_sentence(const CompareResult& result) {
  const Misfit& misfit = result.misfit;
  const MisfitSummary& s = misfit.summary;
  const double excess = s.nll_se > 0 ? (s.nll_per_pixel - s.nll_expected) / s.nll_se : 0.0;
  std::string out;
  if (misfit.failing.empty()) {
    out = fmt::format(
        "The model fits this capture: no region fails at alpha {:g} ({} tests), and the NLL is {:+.1f} "
        "standard errors from what the model expects",
        result.alpha, s.tests, excess);
  } else {
    out = fmt::format("The model fails in {} region{}, most in {}", misfit.failing.size(),
                      misfit.failing.size() == 1 ? "" : "s", where_it_fails(result));
    if (const std::string unit = unit_spread_words(result); !unit.empty()) {
      out +=
          ". " + std::string(1, static_cast<char>(std::toupper(static_cast<unsigned char>(unit[0])))) + unit.substr(1);
    }
  }
  if (result.diagnosis && (!misfit.failing.empty() || !result.diagnosis->selected.empty())) {
    out += "; " + diagnosis_words(*result.diagnosis);
  } else if (!result.diagnosis && !misfit.failing.empty()) {
    out += unit_spread_words(result).empty()
               ? "; run the same compare with --diagnose to name the missing effect"
               : "; run the same compare with --diagnose to fit this unit's own noise and name what else is missing";
  }
  if (!result.next_command.empty()) out += ": run `" + result.next_command + "`";
  return out + ".";
}

}  // namespace lidartwin
