// radiometry (lidar-physics.md section 2): the radar equation, measured levels, the channels.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {
// The radar equation of lidar-physics.md section 2.2 with the default parameters, written again.
double expected_signal(double r, double rho_app, double gain = 1.0, double alpha = 0.0) {
  const double g = 1.0 / (1.0 + std::pow(8.0 / r, 3.8));
  return gain * 1.38e5 * rho_app * g * std::exp(-2.0 * alpha * r) / (r * r);
}
}  // namespace

TEST(Radiometry, SignalFollowsTheRadarEquation) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}, {"attenuation_per_m", 0.002}}}));
  ColumnContext context;
  context.signal_gain = 2.0f;
  double worst = 0.0;
  for (float r = 0.25f; r < 520.0f; r *= 1.0137f) {
    for (const float rho : {0.05f, 0.1f, 0.9f}) {
      for (const float cosine : {1.0f, 0.5f, 0.1f}) {
        const IdealReturn in = surface(r, rho, cosine);
        const double want = expected_signal(r, static_cast<double>(rho * cosine), 2.0, 0.002);
        const double got = chain.predict(in, context).signal_photons;
        worst = std::max(worst, std::abs(got / want - 1.0));
        ASSERT_NEAR(got / want, 1.0, 2e-4) << "r " << r << " rho " << rho << " cos " << cosine;
      }
    }
  }
  std::printf("  radiometry: worst relative error of the tabulated range law %.2e\n", worst);
}

TEST(Radiometry, DefaultsReproduceTheMeasuredSignalLevels) {
  // lidar-physics.md Appendix A, OS1-32 FW 2.1: median S r^2 at reflectivity 8-12 per range band.
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}}}));
  struct Band {
    double from_m, to_m, median_s_r2, tolerance;
  };
  // Far field within 5 %; the near-field roll-off (steep, few samples at 2-4 m) within 35 %.
  for (const Band& band : {Band{2, 4, 244, 0.35}, Band{4, 8, 3369, 0.35}, Band{8, 16, 8238, 0.35},
                           Band{16, 32, 13486, 0.05}, Band{32, 64, 13842, 0.05}}) {
    const float r = static_cast<float>(std::sqrt(band.from_m * band.to_m));
    const double s_r2 = chain.predict(surface(r, 0.1f), {}).signal_photons * static_cast<double>(r * r);
    std::printf("  radiometry: %2.0f-%2.0f m  S r^2 %7.0f vs measured median %6.0f\n", band.from_m, band.to_m, s_r2,
                band.median_s_r2);
    EXPECT_NEAR(s_r2 / band.median_s_r2, 1.0, band.tolerance) << band.from_m << "-" << band.to_m << " m";
  }
}

TEST(Radiometry, ReflectivityAndNearIrChannels) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"},
                                                   {"ambient_photons", 300.0},
                                                   {"sky_photons", 12.0},
                                                   {"retro_reflectance", 50.0},
                                                   {"reflectivity_255", 50.0}}}));
  std::vector<IdealReturn> column{surface(10.0f, 0.5f), surface(10.0f, 0.8f, 0.5f), surface(10.0f, 0.1f), IdealReturn{},
                                  surface(10.0f, 0.3f)};
  column[2].retroreflective = 1;
  column[4].specular = 0.5f;  // normal incidence: the specular lobe adds its full 0.5
  std::vector<Measurement> out(column.size());
  chain.simulate(column, {}, out);
  EXPECT_FLOAT_EQ(out[0].reflectivity, 50.0f);
  EXPECT_FLOAT_EQ(out[1].reflectivity, 40.0f);   // 0.8 * cos 60 deg
  EXPECT_FLOAT_EQ(out[2].reflectivity, 255.0f);  // retro_reflectance == reflectivity_255
  EXPECT_FLOAT_EQ(out[4].reflectivity, 80.0f);
  EXPECT_FLOAT_EQ(out[0].near_ir_photons, 150.0f);
  EXPECT_FLOAT_EQ(out[3].near_ir_photons, 12.0f);  // sky
  EXPECT_EQ(out[3].signal_photons, 0.0f);
  EXPECT_EQ(out[3].range_m, 0.0f);
  // Retroreflectors land in the 101-255 band, monotonically in rho_app.
  float previous = 100.0f;
  for (const double retro : {1.5, 3.0, 10.0, 30.0}) {
    const EffectChain c = chain_of(json::array({{{"name", "radiometry"}, {"retro_reflectance", retro}}}));
    c.simulate(column, {}, out);
    EXPECT_GT(out[2].reflectivity, previous);
    EXPECT_LE(out[2].reflectivity, 255.0f);
    previous = out[2].reflectivity;
  }
}

TEST(Radiometry, SimulateReportsWhatPredictExpects) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1}));
  std::vector<IdealReturn> column;
  for (size_t b = 0; b < kBeams; ++b)
    column.push_back(surface(0.5f + 0.9f * static_cast<float>(b), 0.01f * static_cast<float>(b % 100), 0.7f));
  std::vector<Measurement> out(kBeams);
  ColumnContext context;
  context.signal_gain = 0.5f;
  chain.simulate(column, context, out);
  for (size_t b = 0; b < kBeams; ++b) {
    const Prediction p = chain.predict(column[b], context);
    EXPECT_EQ(static_cast<double>(out[b].signal_photons), p.signal_photons) << b;
    EXPECT_EQ(static_cast<double>(out[b].near_ir_photons), p.near_ir_photons) << b;
  }
}
