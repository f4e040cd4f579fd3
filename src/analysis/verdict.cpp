// The report's first sentence (report.json's "verdict_sentence"): what is wrong, in words, and what
// to do next. The terminal and report.html both lead with it.
#include <algorithm>
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
  }
  if (result.diagnosis && (!misfit.failing.empty() || !result.diagnosis->selected.empty())) {
    out += "; " + diagnosis_words(*result.diagnosis);
  } else if (!result.diagnosis && !misfit.failing.empty()) {
    out += "; run the same compare with --diagnose to name the missing effect";
  }
  if (!result.next_command.empty()) out += ": run `" + result.next_command + "`";
  return out + ".";
}

}  // namespace lidartwin
