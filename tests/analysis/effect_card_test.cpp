// What the analysis knows of an effect it reads from the effect's card (effect_card.h): an effect
// that exists only in this test, registered with a card that makes it a candidate, is tried by the
// diagnosis, kept and fitted, and `fit --add`'s library call fits it, with no other change. Without
// that card the diagnosis leaves it alone.
#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "analysis/synthetic_table.h"
#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/misfit.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"

namespace lidartwin {
namespace {

// Every return reads k r^2 long: a shape no library effect has (E10's scales grow as r, E3's walk
// follows the signal, E12's drift the time).
class SquareLawBias final : public Effect {
 public:
  explicit SquareLawBias(std::string name, double k) : name_(std::move(name)), k_(k) {}
  std::string_view name() const override { return name_; }
  void simulate(std::span<const IdealReturn>, const ColumnContext&, MeasuredColumn& measured) const override {
    for (float& r : measured.range_m) {
      const auto range = static_cast<double>(r);
      if (r != 0.0f) r += static_cast<float>(k_ * range * range);
    }
  }
  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    const auto range = static_cast<double>(ideal.range_m);
    if (ideal.hit()) prediction.bias_m += k_ * range * range;
  }
  std::vector<EffectParameter> parameters() const override { return {{"k_per_m", k_, -1e-3, 1e-3}}; }
  std::unique_ptr<Effect> with_parameters(std::span<const double> values) const override {
    if (std::abs(values[0]) > 1e-3) throw InputError(name_ + ": /k_per_m: must be in [-0.001, 0.001]");
    return std::make_unique<SquareLawBias>(name_, values[0]);
  }
  bool adds_returns() const override { return false; }

 private:
  std::string name_;
  double k_;
};

constexpr double kTrueK = 1e-5;  // 36 mm at 60 m, against a 20 mm sigma

void register_square_law(const std::string& name, EffectCard card) {
  register_effect(
      name,
      [name](const nlohmann::json& p, const json_reader::Location&) {
        return std::make_unique<SquareLawBias>(name, p.value("k_per_m", 0.0));
      },
      std::move(card));
}

// The synthetic scene (1-60 m, sigma 20 mm) measured with the square law's bias.
PixelTable biased_table() {
  std::mt19937_64 rng(3);
  PixelTable t = test::synthetic_layout();
  std::normal_distribution<double> noise(0.0, 0.02);
  for (size_t i = 0; i < t.size(); ++i) {
    const double ideal = static_cast<double>(t.ideal_range_m[i]);
    t.range_m[i] = static_cast<float>(std::round((ideal + kTrueK * ideal * ideal + noise(rng)) * 1000.0) / 1000.0);
  }
  return t;
}

// The profile: the table's own sigma, 20 mm at every range.
EffectChain profile_chain() {
  return EffectChain::from_json(
      nlohmann::json::parse(R"([{"name": "range_noise_linear", "sigma0_m": 0.02, "sigma_max_m": 0.02,
                                 "range_max_m": 100}])"),
      "test profile");
}

TEST(EffectCard, AnEffectRegisteredWithACandidatesCardIsDiagnosedAndFitted) {
  register_square_law("test_square_law_bias", {.catalogue = "", .candidate = true, .fit = {{"k_per_m", 0.0, 2e-6}}});
  const std::vector<std::string> candidates = candidate_effects();
  EXPECT_NE(std::find(candidates.begin(), candidates.end(), "test_square_law_bias"), candidates.end());

  const PixelTable table = biased_table();
  const EffectChain chain = profile_chain();
  const Misfit misfit = find_misfit(table, score_pixels(table), 4, {});
  ASSERT_FALSE(misfit.failing.empty());
  DiagnoseOptions options;
  options.max_effects = 1;
  options.max_pixels = 30000;  // every 4th pixel: a unit test's seconds
  const Diagnosis d = diagnose(table, chain, misfit, options);
  ASSERT_FALSE(d.selected.empty()) << d.verdict;
  const Candidate& kept = d.selected.front();
  EXPECT_EQ(kept.effect, "test_square_law_bias");
  ASSERT_EQ(kept.params.size(), 1u);
  EXPECT_NEAR(kept.params[0].value, kTrueK, 2e-7);
  // Within four standard errors of the truth (a 95 % interval is 3.92 of them wide).
  const double se = (kept.params[0].ci95_hi - kept.params[0].ci95_lo) / 3.92;
  EXPECT_GT(se, 0.0);
  EXPECT_LT(std::abs(kept.params[0].value - kTrueK), 4.0 * se);

  const std::vector<Candidate> fitted = fit_effects(table, chain, std::vector<std::string>{"test_square_law_bias"});
  ASSERT_EQ(fitted.size(), 1u);
  EXPECT_NEAR(fitted[0].params[0].value, kTrueK, 2e-7);
}

TEST(EffectCard, WithoutACandidatesCardTheDiagnosisLeavesAnEffectAlone) {
  register_square_law("test_square_law_uncarded", {});
  const std::vector<std::string> candidates = candidate_effects();
  EXPECT_EQ(std::find(candidates.begin(), candidates.end(), "test_square_law_uncarded"), candidates.end());
  const PixelTable table = biased_table();
  const Misfit misfit = find_misfit(table, score_pixels(table), 4, {});
  DiagnoseOptions options;
  options.max_effects = 1;
  options.max_pixels = 30000;  // every 4th pixel: a unit test's seconds
  const Diagnosis d = diagnose(table, profile_chain(), misfit, options);
  for (const Candidate& c : d.ranked) EXPECT_NE(c.effect, "test_square_law_uncarded");
  // A user's effect without a catalogue id is still fitted on request (fit --add).
  const std::vector<Candidate> fitted =
      fit_effects(table, profile_chain(), std::vector<std::string>{"test_square_law_uncarded"});
  ASSERT_EQ(fitted.size(), 1u);
  EXPECT_NEAR(fitted[0].params[0].value, kTrueK, 2e-7);
}

}  // namespace
}  // namespace lidartwin
