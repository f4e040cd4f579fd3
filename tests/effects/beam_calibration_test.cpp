// beam_calibration (E10): each beam of a unit keeps its own range offset and scale, drawn from the
// unit seed or given as per-beam tables; simulate applies exactly what predict says, beam by beam.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {

json unit(double seed) {
  return {{"name", "beam_calibration"}, {"offset_sigma_m", 0.02}, {"scale_sigma", 0.001}, {"unit_seed", seed}};
}

std::vector<IdealReturn> column_at(float range_m) {
  std::vector<IdealReturn> column(kBeams, surface(range_m));
  for (size_t b = 0; b < kBeams; ++b) column[b].beam = static_cast<uint16_t>(b);
  return column;
}

TEST(BeamCalibration, EachBeamIsShiftedAsPredictedTheSameInEveryFrame) {
  const EffectChain chain = chain_of(json::array({unit(7)}));
  const std::vector<IdealReturn> column = column_at(30.0f);
  std::vector<Measurement> first(kBeams), later(kBeams);
  chain.simulate(column, ColumnContext{1, 0, 0}, first);
  chain.simulate(column, ColumnContext{99, 5, 700}, later);  // another seed, frame and column
  double sum = 0.0, sum2 = 0.0;
  for (size_t b = 0; b < kBeams; ++b) {
    const Prediction p = chain.predict(column[b], {});
    EXPECT_NEAR(static_cast<double>(first[b].range_m), 30.0 + p.bias_m, 1e-5) << "beam " << b;
    EXPECT_EQ(first[b].range_m, later[b].range_m) << "beam " << b;
    sum += p.bias_m;
    sum2 += p.bias_m * p.bias_m;
  }
  // Offsets N(0, 2 cm) plus 30 m x N(0, 0.1 %) = 3 cm: sd about 3.6 cm over 128 beams.
  const double sd = std::sqrt(sum2 / kBeams - (sum / kBeams) * (sum / kBeams));
  EXPECT_GT(sd, 0.025);
  EXPECT_LT(sd, 0.05);
}

TEST(BeamCalibration, AnotherUnitSeedIsAnotherUnit) {
  const std::vector<IdealReturn> column = column_at(10.0f);
  const Prediction a = chain_of(json::array({unit(1)})).predict(column[3], {});
  const Prediction b = chain_of(json::array({unit(2)})).predict(column[3], {});
  EXPECT_NE(a.bias_m, b.bias_m);
  EXPECT_EQ(a.bias_m, chain_of(json::array({unit(1)})).predict(column[3], {}).bias_m);
}

TEST(BeamCalibration, OffByDefault) {
  const Prediction p = chain_of(json::array({{{"name", "beam_calibration"}}})).predict(column_at(10.0f)[5], {});
  EXPECT_EQ(p.bias_m, 0.0);
}

// Tables, as the diagnosis fits them: beam b shifted by offsets_m[b] and scaled by scales[b];
// beams beyond the tables left alone; the tables are the parameters (JSON pointers) and survive a
// round trip through to_json and with_parameters.
TEST(BeamCalibration, PerBeamTablesShiftEachBeamByItsOwnValues) {
  const json tables = {{"name", "beam_calibration"}, {"offsets_m", {0.01, -0.02, 0.0}}, {"scales", {0.0, 0.001}}};
  const EffectChain chain = chain_of(json::array({tables}));
  const std::vector<IdealReturn> column = column_at(20.0f);
  std::vector<Measurement> measured(kBeams);
  chain.simulate(column, ColumnContext{1, 0, 0}, measured);
  EXPECT_NEAR(measured[0].range_m, 20.01f, 1e-5f);
  EXPECT_NEAR(measured[1].range_m, 20.0f * 1.001f - 0.02f, 1e-5f);
  EXPECT_NEAR(measured[2].range_m, 20.0f, 1e-5f);
  EXPECT_NEAR(measured[3].range_m, 20.0f, 1e-5f);  // beyond the tables
  for (size_t b = 0; b < 4; ++b) {
    EXPECT_NEAR(20.0 + chain.predict(column[b], {}).bias_m, static_cast<double>(measured[b].range_m), 1e-5);
  }
  const auto& effect = *chain.effects()[0];
  ASSERT_EQ(effect.parameters().size(), 6u);  // the scales table padded to the offsets' length
  EXPECT_EQ(effect.parameters()[1].name, "offsets_m/1");
  EXPECT_EQ(effect.to_json()["scales"], json({0.0, 0.001, 0.0}));
  const std::vector<double> values{0.0, 0.0, 0.03, 0.0, 0.0, 0.0};
  EXPECT_NEAR(effect.with_parameters(values)->to_json()["offsets_m"][2].get<double>(), 0.03, 1e-12);
}

TEST(BeamCalibration, AUnitAndTablesTogetherOrValuesOutOfBoundsAreErrors) {
  const auto error_of = [](const json& effect) {
    try {
      (void)EffectChain::from_json(json::array({effect}), Location{"e10.json", "/effects"});
    } catch (const lidartwin::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error_of({{"name", "beam_calibration"}, {"offset_sigma_m", 0.01}, {"offsets_m", {0.0}}}),
            "e10.json: /effects/0: give either a unit (offset_sigma_m, scale_sigma, unit_seed) or per-beam tables "
            "(offsets_m, scales), not both");
  EXPECT_EQ(error_of({{"name", "beam_calibration"}, {"offsets_m", {0.0, 0.7}}}),
            "e10.json: /effects/0/offsets_m/1: must be in [-0.5, 0.5], got 0.7");
  EXPECT_EQ(error_of({{"name", "beam_calibration"}, {"scales", 0.001}}),
            "e10.json: /effects/0/scales: must be an array of per-beam values, got a number 0.001");
}

}  // namespace
