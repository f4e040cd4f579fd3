// report.json's "diagnosis" (docs/compare-report.md).
#include "lidartwin/analysis/diagnosis.h"

#include <cmath>

#include <fmt/format.h>

namespace lidartwin {
namespace {

nlohmann::json params_json(const std::vector<FittedParameter>& params) {
  nlohmann::json out = nlohmann::json::object();
  for (const FittedParameter& p : params) {
    out[p.name] = {{"value", p.value}, {"ci95", {p.ci95_lo, p.ci95_hi}}};
    if (!std::isnan(p.robust_lo)) out[p.name]["ci95_robust"] = {p.robust_lo, p.robust_hi};
    if (!std::isnan(p.lower)) out[p.name]["bounds"] = {p.lower, p.upper};
    if (const std::string note = bound_note(p); !note.empty()) out[p.name]["bound"] = note;
  }
  return out;
}

nlohmann::json candidate_json(const Candidate& c) {
  return {{"effect", c.effect},       {"catalogue", c.catalogue}, {"delta_bic", c.delta_bic},
          {"delta_nll", c.delta_nll}, {"p_value", c.p_value},     {"params", params_json(c.params)},
          {"repairs", c.repairs}};
}

// The replacement with its own parameters, and how it compares with the best additive candidate
// of its round (no p-value: the two laws are not nested).
nlohmann::json replacement_json(const Replacement& r) {
  nlohmann::json with = candidate_json(r.with);
  with.erase("p_value");
  with.erase("repairs");
  return {
      {"effect", r.effect},
      {"catalogue", r.catalogue},
      {"index", r.index},
      {"replacement", with},
      {"delta_bic", r.with.delta_bic},
      {"delta_nll", r.with.delta_nll},
      {"parameters", {{"added", r.with.params.size()}, {"removed", r.parameters_removed}}},
      {"additive", r.additive.empty() ? nlohmann::json(nullptr)
                                      : nlohmann::json{{"effect", r.additive}, {"delta_bic", r.additive_delta_bic}}},
      {"delta_bic_vs_additive", r.with.delta_bic - r.additive_delta_bic},
      {"repairs", r.with.repairs},
      {"sentence", r.sentence}};
}

}  // namespace

nlohmann::json diagnosis_json(const Diagnosis& d) {
  nlohmann::json ranked = nlohmann::json::array(), selected = nlohmann::json::array();
  for (const Candidate& c : d.ranked) ranked.push_back(candidate_json(c));
  for (const Candidate& c : d.selected) selected.push_back(candidate_json(c));
  nlohmann::json refits = nlohmann::json::array();
  for (const ParameterMisfit& m : d.parameter_misfit) {
    nlohmann::json entry = candidate_json(m.refit);
    entry.erase("repairs");
    nlohmann::json old_values = nlohmann::json::object();
    for (const auto& [name, value] : m.old_values) old_values[name] = value;
    entry["old"] = old_values;
    entry["index"] = m.index;
    entry["channel"] = m.channel;
    refits.push_back(entry);
  }
  nlohmann::json unexplained = nlohmann::json::array();
  for (const UnexplainedMisfit& u : d.unexplained) {
    nlohmann::json tests = nlohmann::json::array();
    for (const FeatureTest& t : u.tests) {
      tests.push_back({{"feature", t.feature}, {"chi2", t.chi2}, {"dof", t.dof}, {"p_value", t.p_value}});
    }
    unexplained.push_back({{"quantity", u.quantity},
                           {"features", u.features},
                           {"not_features", u.not_features},
                           {"size", u.size},
                           {"unit", u.unit},
                           {"regions", u.regions},
                           {"sentence", u.sentence},
                           {"tests", tests}});
  }
  nlohmann::json not_selected = nlohmann::json::array();
  for (const NotSelected& n : d.not_selected) {
    not_selected.push_back(
        {{"effect", n.effect},
         {"delta_bic", n.delta_bic},
         {"pattern", {{"quantity", n.quantity}, {"feature", n.feature}, {"delta_bic", n.pattern_delta_bic}}},
         {"delta_bic_given_pattern", n.delta_bic_given_pattern},
         {"pattern_delta_bic_given_effect", n.pattern_delta_bic_given_effect},
         {"sentence", n.sentence}});
  }
  nlohmann::json shared = nlohmann::json::array();
  for (const SharedMisfit& s : d.shared) {
    shared.push_back({{"effect", s.effect},
                      {"with", s.with},
                      {"delta_bic_alone", s.delta_bic_alone},
                      {"delta_bic_given", s.delta_bic_given},
                      {"with_delta_bic_given", s.with_delta_bic_given},
                      {"repairs", s.repairs},
                      {"sentence", s.sentence}});
  }
  nlohmann::json replace = nlohmann::json::array();
  for (const Replacement& r : d.replace) replace.push_back(replacement_json(r));
  return {
      {"verdict", d.verdict},
      {"not_selected", not_selected},
      {"shared", shared},
      {"ranked", ranked},
      {"selected", selected},
      {"pixels", d.pixels},
      {"unexplained", unexplained},
      {"parameter_misfit", refits},
      {"replace", replace},
      {"remaining",
       {{"failing_regions", d.remaining_failing}, {"excess_se", d.remaining_excess_se}, {"note", d.remaining_note}}},
      {"intervals_caveat", d.intervals_caveat}};
}

std::string bound_note(const FittedParameter& p) {
  if (std::isnan(p.lower) || std::isnan(p.upper) || !(p.upper > p.lower)) return "";
  const double close = 1e-6 * (p.upper - p.lower);
  if (p.value <= p.lower + close) return fmt::format("at its lower bound {:.4g}", p.lower);
  if (p.value >= p.upper - close) return fmt::format("at its upper bound {:.4g}", p.upper);
  if (p.ci95_lo <= p.lower + close && p.ci95_hi >= p.upper - close) {
    return fmt::format("its interval spans its bounds {:.4g} .. {:.4g}", p.lower, p.upper);
  }
  return "";
}

}  // namespace lidartwin
