// vibration (E11): columns cast with Embree from the jittered poses the effect gives, at random
// times, against predict's bias and spread of a plane's range, at several incidences and at the
// bounds of the jitter; and the jitter as a pure function of the column's time and the unit.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/caster/column_caster.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/scene/scene.h"
#include "support/test_scene.h"

namespace lidartwin {
namespace {

using nlohmann::json;
constexpr double kDegree = std::numbers::pi / 180.0;

json vibration(double angular_deg, double translation_m, double low_hz = 20.0, double high_hz = 200.0,
               double unit = 3.0) {
  return {{"name", "vibration"},   {"angular_rms_deg", angular_deg}, {"translation_rms_m", translation_m},
          {"band_low_hz", low_hz}, {"band_high_hz", high_hz},        {"unit_seed", unit}};
}

EffectChain chain_of(const json& effect) { return EffectChain::from_json(json::array({effect}), "test"); }

class VibrationScene : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lidartwin_vibration_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  // A large vertical wall through (12, 0, 0) whose normal is turned `incidence_deg` from -x about z.
  Scene wall(double incidence_deg) const {
    const double a = incidence_deg * kDegree;
    const Eigen::Vector3f c(12.0f, 0.0f, 0.0f);
    const Eigen::Vector3f along(static_cast<float>(-std::sin(a)), static_cast<float>(std::cos(a)), 0.0f);
    const Eigen::Vector3f up(0.0f, 0.0f, 1.0f);
    const auto path = dir_ / ("wall" + std::to_string(static_cast<int>(incidence_deg)) + ".glb");
    test::write_glb(path, {test::quad("wall", c - 150 * along - 150 * up, c + 150 * along - 150 * up,
                                      c + 150 * along + 150 * up, c - 150 * along + 150 * up, 0.3f)});
    return Scene::load(path);
  }
  std::filesystem::path dir_;
};

TEST_F(VibrationScene, PlaneRangesShiftAndSpreadAsPredicted) {
  const BeamGeometry geometry(load_profile("os1-128").beams, 1024);
  constexpr int kColumn = 512;  // looks along +x, at the wall
  constexpr int kCasts = 6000;
  struct Case {
    double angular_deg, translation_m, low_hz, high_hz;
  };
  for (const double incidence : {0.0, 45.0, 70.0}) {
    const Scene scene = wall(incidence);
    const ColumnCaster caster(scene, geometry, 200.0f);
    std::vector<IdealReturn> ideal(128), moved(128);
    caster.cast(kColumn, Pose{}, ideal);
    for (const Case& k : {Case{0.2, 0.0, 20.0, 200.0}, Case{0.0, 0.01, 20.0, 200.0}, Case{1.0, 0.05, 0.1, 10000.0},
                          Case{0.05, 0.002, 150.0, 151.0}}) {
      const EffectChain chain = chain_of(vibration(k.angular_deg, k.translation_m, k.low_hz, k.high_hz));
      ASSERT_TRUE(chain.moves_sensor());
      std::mt19937_64 rng(static_cast<uint64_t>(incidence * 1000 + k.angular_deg * 100));
      std::uniform_real_distribution<double> time(0.0, 5000.0);
      const std::vector<int> rows{10, 64, 118};
      std::vector<double> sum(rows.size()), sum2(rows.size());
      ColumnContext context;
      for (int i = 0; i < kCasts; ++i) {
        context.time_s = time(rng);
        caster.cast(kColumn, chain.moved_pose(Pose{}, context), moved);
        for (size_t j = 0; j < rows.size(); ++j) {
          const auto r = static_cast<size_t>(rows[j]);
          ASSERT_TRUE(moved[r].hit());
          const double e = static_cast<double>(moved[r].range_m) - static_cast<double>(ideal[r].range_m);
          sum[j] += e;
          sum2[j] += e * e;
        }
      }
      for (size_t j = 0; j < rows.size(); ++j) {
        const IdealReturn& in = ideal[static_cast<size_t>(rows[j])];
        const Prediction p = chain.predict(in, context);
        const double mean = sum[j] / kCasts;
        const double sd = std::sqrt((sum2[j] - sum[j] * sum[j] / kCasts) / (kCasts - 1));
        const double predicted_sd = std::sqrt(p.variance_m2);
        std::printf(
            "  incidence %4.1f deg (row %3d, %5.1f deg, %5.2f m) angular %.2f deg translation %.3f m, band %g-%g Hz: "
            "mean %+.5f vs %+.5f m, sd %.5f vs %.5f m\n",
            incidence, rows[j], std::acos(static_cast<double>(in.cos_incidence)) / kDegree,
            static_cast<double>(in.range_m), k.angular_deg, k.translation_m, k.low_hz, k.high_hz, mean, p.bias_m, sd,
            predicted_sd);
        const double float_ulp = 2e-6;  // ranges are floats
        EXPECT_NEAR(mean, p.bias_m, 5.0 * predicted_sd / std::sqrt(kCasts) + float_ulp);
        EXPECT_NEAR(sd, predicted_sd, 5.0 * predicted_sd / std::sqrt(2.0 * kCasts) + float_ulp);
      }
    }
  }
}

TEST(Vibration, TheJitterIsAFunctionOfTheColumnsTimeAndTheUnit) {
  const EffectChain a = chain_of(vibration(0.1, 0.01)), same = chain_of(vibration(0.1, 0.01));
  const EffectChain other_unit = chain_of(vibration(0.1, 0.01, 20.0, 200.0, 4.0));
  ColumnContext at;
  at.time_s = 12.345;
  ColumnContext elsewhere = at;
  elsewhere.frame = 99;  // frame, column and seed key noise, not the mount's motion
  elsewhere.column = 7;
  elsewhere.seed = 5;
  const Pose p = a.moved_pose(Pose{}, at);
  EXPECT_TRUE(p.translation.isApprox(same.moved_pose(Pose{}, elsewhere).translation));
  EXPECT_TRUE(p.rotation.isApprox(same.moved_pose(Pose{}, elsewhere).rotation));
  EXPECT_FALSE(p.translation.isApprox(other_unit.moved_pose(Pose{}, at).translation));
  ColumnContext later = at;
  later.time_s += 0.001;
  EXPECT_FALSE(p.translation.isApprox(a.moved_pose(Pose{}, later).translation));
  EXPECT_GT(p.translation.norm(), 0.0);
  EXPECT_LT(p.translation.norm(), 0.1);
  // Off at zero amplitude: the renderer then casts from the trajectory's poses.
  EXPECT_FALSE(chain_of(vibration(0.0, 0.0)).moves_sensor());
}

TEST(Vibration, BadParametersNameTheEffectAndTheParameter) {
  try {
    EffectChain::from_json(json::array({vibration(0.1, 0.0, 200.0, 50.0)}),
                           json_reader::Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/0/band_high_hz: must be above band_low_hz (200), got 50");
  }
  try {
    EffectChain::from_json(json::array({vibration(3.0, 0.0)}), json_reader::Location{"p.json", "/effects"});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "p.json: /effects/0/angular_rms_deg: must be in [0, 1], got 3");
  }
}

}  // namespace
}  // namespace lidartwin
