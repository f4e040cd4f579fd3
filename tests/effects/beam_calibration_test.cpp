// beam_calibration (E10): each beam of a unit keeps its own range offset and scale, drawn from the
// unit seed; simulate applies exactly what predict says, beam by beam.
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

}  // namespace
