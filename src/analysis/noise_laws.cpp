// The range-noise forms tried in place of a profile's own law (noise_laws.h).
#include "noise_laws.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace lidartwin::analysis_detail {
namespace {

// A plateau no more fitted pixels reach than this keeps the datasheet's sigma: its value would be
// a guess, and a parameter the data do not constrain would still cost ln n in the BIC.
constexpr size_t kMinPlateauPixels = 100;

bool has_effect(const EffectChain& chain, std::string_view name) {
  return std::any_of(chain.effects().begin(), chain.effects().end(), [&](const auto& e) { return e->name() == name; });
}

// E2 alone: k and the floor that a sigma(r) law would otherwise carry. Starts as the candidate's k
// does, with a floor of a few millimetres (lidar-physics.md E1: "sigma_floor a few mm").
CandidateSpec signal_precision_form() {
  return {"signal_precision", {{"k_m", 0.05, 0.05}, {"floor_m", 0.005, 0.005}}, nullptr};
}

// The linear law from the table's first knot's sigma to its last's, over the table's span.
CandidateSpec linear_form(const Effect& table) {
  std::vector<double> ranges, sigmas;  // parameters(): points_m/k/0 (range), points_m/k/1 (sigma)
  for (const EffectParameter& p : table.parameters()) (p.name.ends_with("/0") ? ranges : sigmas).push_back(p.value);
  const double sigma0 = sigmas.front(), sigma_max = sigmas.back();
  const nlohmann::json start = {
      {"name", "range_noise_linear"}, {"sigma0_m", sigma0}, {"sigma_max_m", sigma_max}, {"range_max_m", ranges.back()}};
  return {
      "range_noise_linear",
      {{"sigma0_m", sigma0, std::max(0.2 * sigma0, 1e-4)}, {"sigma_max_m", sigma_max, std::max(0.2 * sigma_max, 1e-4)}},
      start};
}

// The datasheet table with one free sigma per plateau (a run of knots of equal sigma) that the
// rows reach: a pixel belongs to the plateau whose span, extended halfway into the ramps on either
// side, holds its ideal range.
CandidateSpec table_form(const nlohmann::json& datasheet, const PixelTable& t, const FitRows& rows) {
  const nlohmann::json& points = datasheet.at("points_m");
  struct Plateau {
    size_t first, last;
    double lower, upper;
    size_t pixels = 0;
  };
  std::vector<Plateau> plateaus;
  for (size_t k = 0; k < points.size(); ++k) {
    const double sigma = points[k][1].get<double>();
    if (!plateaus.empty() && points[plateaus.back().last][1].get<double>() == sigma) {
      plateaus.back().last = k;
    } else {
      plateaus.push_back({k, k, 0.0, 0.0});
    }
  }
  for (size_t p = 0; p < plateaus.size(); ++p) {
    const auto range = [&](size_t k) { return points[k][0].get<double>(); };
    plateaus[p].lower = p == 0 ? 0.0 : 0.5 * (range(plateaus[p - 1].last) + range(plateaus[p].first));
    plateaus[p].upper = p + 1 == plateaus.size() ? std::numeric_limits<double>::infinity()
                                                 : 0.5 * (range(plateaus[p].last) + range(plateaus[p + 1].first));
  }
  for (const size_t i : rows) {
    const double r = static_cast<double>(t.ideal_range_m[i]);
    for (Plateau& p : plateaus) p.pixels += r >= p.lower && r < p.upper;
  }
  CandidateSpec spec{"range_noise_piecewise", {}, {{"name", "range_noise_piecewise"}, {"points_m", points}}};
  for (const Plateau& p : plateaus) {
    if (p.pixels < kMinPlateauPixels) continue;
    const double sigma = points[p.first][1].get<double>();
    FreeParameter free{"points_m/" + std::to_string(p.first) + "/1", sigma, std::max(0.2 * sigma, 1e-4)};
    for (size_t k = p.first + 1; k <= p.last; ++k) free.tied.push_back("points_m/" + std::to_string(k) + "/1");
    spec.free.push_back(std::move(free));
  }
  return spec;
}

}  // namespace

bool is_range_noise_law(std::string_view effect) {
  return effect == "range_noise_linear" || effect == "range_noise_piecewise";
}

std::optional<size_t> range_noise_index(const EffectChain& chain) {
  for (size_t i = 0; i < chain.effects().size(); ++i) {
    if (is_range_noise_law(chain.effects()[i]->name())) return i;
  }
  return std::nullopt;
}

std::vector<CandidateSpec> noise_law_forms(const EffectChain& chain, size_t index, const PixelTable& t,
                                           const FitRows& rows, const std::optional<nlohmann::json>& datasheet) {
  const Effect& law = *chain.effects()[index];
  std::vector<CandidateSpec> forms;
  if (has_effect(chain, "radiometry") && !has_effect(chain, "signal_precision")) {
    forms.push_back(signal_precision_form());
  }
  if (law.name() == "range_noise_piecewise") forms.push_back(linear_form(law));
  if (law.name() == "range_noise_linear" && datasheet) {
    CandidateSpec table = table_form(*datasheet, t, rows);
    if (!table.free.empty()) forms.push_back(std::move(table));
  }
  return forms;
}

}  // namespace lidartwin::analysis_detail
