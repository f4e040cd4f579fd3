// Effects the library does not have (lidar-physics.md 3.4's last step): a capture of the calibration
// hall with a hidden effect that exists only in this test, compared with `lidartwin compare
// --diagnose` as a user runs it. The report's diagnosis.unexplained says which features the misfit
// follows and which it does not; the test then writes the effect a user would write from that
// sentence, registers it, fits it, and the NLL per pixel on held-out frames falls to the level of
// the generator's own model.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numeric>
#include <span>
#include <string>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/pixel_table.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/record/recorder.h"
#include "lidartwin/scene/scene.h"
#include "support/table_profile.h"

namespace lidartwin::cli_out_of_library_test {
namespace {

namespace fs = std::filesystem;

const fs::path kSource = LIDARTWIN_SOURCE_DIR;
const fs::path kHall = kSource / "scenes/calibration_hall.glb";
constexpr const char* kHallPose = "0 0 4 0 0 0 1";  // scenes/calibration_hall_static.tum
constexpr int kFitFrames = 8;
constexpr int kHeldOutFrames = 6;

// ---- the generators' effects: what the "sensor" does (the analysis never sees these classes) ----

// The pillars' paint (the hall's only surfaces of reflectivity 0.4) reads 25 mm long, as a paint
// whose pigment scatters light below its surface would.
class PaintDepthBias final : public Effect {
 public:
  static constexpr double kBiasM = 0.025;
  std::string_view name() const override { return "test_paint_depth_bias"; }
  void simulate(std::span<const IdealReturn> ideal, const ColumnContext&, MeasuredColumn& measured) const override {
    for (size_t i = 0; i < ideal.size(); ++i) {
      if (measured.range_m[i] != 0.0f && painted(ideal[i])) measured.range_m[i] += static_cast<float>(kBiasM);
    }
  }
  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    if (painted(ideal)) prediction.bias_m += kBiasM;
  }
  std::vector<EffectParameter> parameters() const override { return {}; }
  std::unique_ptr<Effect> with_parameters(std::span<const double>) const override {
    return std::make_unique<PaintDepthBias>();
  }

 private:
  static bool painted(const IdealReturn& r) { return std::abs(r.reflectivity - 0.4f) < 1e-4f; }
};

// Four channels of the detector (rows 20-23) have weak lasers: 40 % of their returns go missing.
class WeakChannels final : public Effect {
 public:
  static constexpr double kLoss = 0.4;
  std::string_view name() const override { return "test_weak_channels"; }
  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    for (uint32_t beam = 20; beam <= 23 && beam < measured.size(); ++beam) {
      if (measured.range_m[beam] == 0.0f || streams(beam).uniform(0) >= kLoss) continue;
      measured.range_m[beam] = 0.0f;
      measured.signal_photons[beam] = 0.0f;
      measured.reflectivity[beam] = 0.0f;
    }
  }
  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    if (ideal.beam >= 20 && ideal.beam <= 23) prediction.p_detect *= 1.0 - kLoss;
  }
  std::vector<EffectParameter> parameters() const override { return {}; }
  std::unique_ptr<Effect> with_parameters(std::span<const double>) const override {
    return std::make_unique<WeakChannels>();
  }
};

// ---- the effects a user writes from the report's sentences ----

// "The unexplained range bias varies with material (material 3: ...)": one material's ranges are
// offset. The material is fixed (read from the report); the offset is fitted.
class MaterialOffset final : public Effect {
 public:
  MaterialOffset(double material, double offset_m) : material_(material), offset_m_(offset_m) {}
  std::string_view name() const override { return "material_offset"; }
  void simulate(std::span<const IdealReturn> ideal, const ColumnContext&, MeasuredColumn& measured) const override {
    for (size_t i = 0; i < ideal.size(); ++i) {
      if (measured.range_m[i] != 0.0f && mine(ideal[i])) measured.range_m[i] += static_cast<float>(offset_m_);
    }
  }
  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    if (mine(ideal)) prediction.bias_m += offset_m_;
  }
  std::vector<EffectParameter> parameters() const override {
    return {{"material", material_, 0.0, 65535.0, true}, {"offset_m", offset_m_, -0.5, 0.5, false}};
  }
  std::unique_ptr<Effect> with_parameters(std::span<const double> values) const override {
    if (std::abs(values[1]) > 0.5) throw InputError("material_offset: /offset_m: must be in [-0.5, 0.5]");
    return std::make_unique<MaterialOffset>(values[0], values[1]);
  }
  static std::unique_ptr<Effect> make(const nlohmann::json& p, const lidartwin::json_reader::Location&) {
    return MaterialOffset(0, 0).with_parameters(std::vector<double>{p.at("material"), p.value("offset_m", 0.0)});
  }

 private:
  bool mine(const IdealReturn& r) const { return static_cast<double>(r.material_id) == material_; }
  double material_;
  double offset_m_;
};

// "The unexplained detection rate varies with beam (beam 21: 60 % return against the model's 100 %
// ...)": some beams lose a share of their returns. Which beams is fixed; the share is fitted.
class BeamLoss final : public Effect {
 public:
  BeamLoss(double first, double last, double loss) : first_(first), last_(last), loss_(loss) {}
  std::string_view name() const override { return "beam_loss"; }
  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    for (uint32_t beam = 0; beam < ideal.size(); ++beam) {
      if (measured.range_m[beam] == 0.0f || !mine(ideal[beam]) || streams(beam).uniform(0) >= loss_) continue;
      measured.range_m[beam] = 0.0f;
      measured.signal_photons[beam] = 0.0f;
      measured.reflectivity[beam] = 0.0f;
    }
  }
  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    if (mine(ideal)) prediction.p_detect *= 1.0 - loss_;
  }
  std::vector<EffectParameter> parameters() const override {
    return {{"first_beam", first_, 0, 127, true}, {"last_beam", last_, 0, 127, true}, {"loss", loss_, 0.0, 0.99}};
  }
  std::unique_ptr<Effect> with_parameters(std::span<const double> values) const override {
    if (values[2] < 0.0 || values[2] > 0.99) throw InputError("beam_loss: /loss: must be in [0, 0.99]");
    return std::make_unique<BeamLoss>(values[0], values[1], values[2]);
  }
  static std::unique_ptr<Effect> make(const nlohmann::json& p, const lidartwin::json_reader::Location&) {
    return BeamLoss(0, 0, 0).with_parameters(
        std::vector<double>{p.at("first_beam"), p.at("last_beam"), p.value("loss", 0.0)});
  }

 private:
  bool mine(const IdealReturn& r) const { return r.beam >= first_ && r.beam <= last_; }
  double first_, last_, loss_;
};

void register_test_effects() {
  static const bool once = [] {
    register_effect("test_paint_depth_bias", [](const nlohmann::json&, const lidartwin::json_reader::Location&) {
      return std::make_unique<PaintDepthBias>();
    });
    register_effect("test_weak_channels", [](const nlohmann::json&, const lidartwin::json_reader::Location&) {
      return std::make_unique<WeakChannels>();
    });
    register_effect("material_offset", MaterialOffset::make);
    register_effect("beam_loss", BeamLoss::make);
    return true;
  }();
  (void)once;
}

// ---- the capture, the report, the fit ----

// os1-64 with the datasheet table's effects (support/table_profile.h): the profile under test.
const fs::path& profile_path() {
  static const fs::path path = table_profiles::table_profile("os1-64");
  return path;
}

nlohmann::json profile_effects() {
  std::ifstream in(profile_path());
  return nlohmann::json::parse(in).at("effects");
}

// {"name": name}: an effect with its defaults.
nlohmann::json named(const std::string& name) {
  nlohmann::json effect = nlohmann::json::object();
  effect["name"] = name;
  return effect;
}

// The profile's chain with `extra` effects before its range limits.
EffectChain chain_with_effects(const std::vector<nlohmann::json>& extra) {
  nlohmann::json effects = profile_effects();
  auto limits = std::find_if(effects.begin(), effects.end(), [](const auto& e) { return e["name"] == "range_limits"; });
  for (const nlohmann::json& effect : extra) limits = effects.insert(limits, effect) + 1;
  return EffectChain::from_json(effects, "test chain");
}

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::path(testing::TempDir()) / ("out_of_library_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The generator: `lidartwin record`'s library call with the hidden effect in the chain.
void record_hidden(const std::string& hidden, const fs::path& out) {
  const SensorProfile profile = load_profile(profile_path().string());
  nlohmann::json config = default_config_params();
  config["lidar_mode"] = "1024x10";
  SensorInfo info;
  info.prod_line = profile.prod_line;
  info.prod_sn = "992200000001";
  info.initialization_id = 4242;
  const Scene scene = Scene::load(kHall);
  const StaticPose pose(parse_pose(kHallPose));
  record({scene, pose, profile.max_range_m, chain_with_effects({named(hidden)}),
          make_metadata(info, profile.beams, config), 5, 0, kFitFrames + kHeldOutFrames, out},
         [](int) {});
}

struct Report {
  int code = -1;
  nlohmann::json json;
};
Report compare_diagnose(const fs::path& capture, const fs::path& out) {
  const std::string command = std::string(LIDARTWIN_BINARY) + " compare --capture " + capture.string() + " --scene " +
                              kHall.string() + " --profile " + profile_path().string() + " --frames " +
                              std::to_string(kFitFrames) + " --diagnose --no-plots --out " + out.string() +
                              " > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  Report r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (r.code == 0) r.json = nlohmann::json::parse(std::ifstream(out / "report.json"));
  return r;
}

const nlohmann::json* unexplained(const nlohmann::json& report, const std::string& quantity) {
  for (const auto& u : report.at("diagnosis").at("unexplained")) {
    if (u.at("quantity") == quantity) return &u;
  }
  return nullptr;
}

bool contains(const nlohmann::json& list, const std::string& name) {
  return std::find(list.begin(), list.end(), name) != list.end();
}

// The capture's pixel table (frames [skip, skip + frames)) predicted by the profile's chain.
PixelTable table_of(const fs::path& capture, size_t frames, size_t skip) {
  const MeasuredCapture measured = read_capture(capture / "capture.pcap", capture / "metadata.json", frames, skip);
  const Scene scene = Scene::load(kHall);
  const StaticPose pose(parse_pose(kHallPose));
  const EffectChain chain = chain_with_effects({});
  WorkerPool pool(0);
  return build_pixel_table({measured, scene, pose, 0.0, chain, load_profile(profile_path().string()).max_range_m},
                           pool);
}

struct Nll {
  double per_pixel = 0.0;
  double se = 0.0;  // its standard error if the model were true
};
Nll nll_of(const PixelTable& table, const EffectChain& chain) {
  const PixelTable predicted = repredicted(table, chain);
  const Misfit misfit = find_misfit(predicted, score_pixels(predicted), kHeldOutFrames, {});
  return {misfit.summary.nll_per_pixel, misfit.summary.nll_se};
}

// The held-out frames under the profile, the profile with the fitted effect, and the generator.
void expect_error_falls_to_the_generators(const fs::path& capture, const nlohmann::json& fitted,
                                          const std::string& hidden) {
  const PixelTable held_out = table_of(capture, kHeldOutFrames, kFitFrames);
  const Nll before = nll_of(held_out, chain_with_effects({}));
  const Nll after = nll_of(held_out, chain_with_effects({fitted}));
  const Nll truth = nll_of(held_out, chain_with_effects({named(hidden)}));
  std::printf("held-out NLL per pixel: profile %.5f, with the fitted effect %.5f, generator %.5f (SE %.5f)\n",
              before.per_pixel, after.per_pixel, truth.per_pixel, truth.se);
  EXPECT_GT(before.per_pixel - truth.per_pixel, 10.0 * truth.se);
  EXPECT_LT(std::abs(after.per_pixel - truth.per_pixel), 2.0 * truth.se);
}

class OutOfLibrary : public ::testing::Test {
 protected:
  void SetUp() override { register_test_effects(); }
};

TEST_F(OutOfLibrary, AMaterialsRangeBiasIsTracedToTheMaterialThenWrittenFittedAndTheErrorFalls) {
  const fs::path dir = temp_dir("paint");
  record_hidden("test_paint_depth_bias", dir / "capture");
  const Report report = compare_diagnose(dir / "capture", dir / "report");
  ASSERT_EQ(report.code, 0);
  const auto& diagnosis = report.json.at("diagnosis");
  EXPECT_EQ(diagnosis.at("verdict"), "missing effect");
  const nlohmann::json* bias = unexplained(report.json, "bias");
  ASSERT_NE(bias, nullptr) << diagnosis.dump(1);
  std::printf("%s\n", bias->at("sentence").get<std::string>().c_str());
  // It follows the material, and neither range, beam, azimuth nor time.
  ASSERT_FALSE(bias->at("features").empty());
  EXPECT_EQ(bias->at("features")[0], "material") << bias->at("sentence");
  for (const char* other : {"range", "beam", "azimuth", "time"}) {
    EXPECT_TRUE(contains(bias->at("not_features"), other)) << other << ": " << bias->at("sentence");
  }
  ASSERT_FALSE(bias->at("regions").empty());
  const std::string worst = bias->at("regions")[0];  // "material 3": the pillars' paint
  ASSERT_EQ(worst.rfind("material ", 0), 0u) << worst;
  EXPECT_NEAR(bias->at("size").get<double>(), PaintDepthBias::kBiasM, 0.003);

  // The user's effect, from the sentence: an offset on that material, fitted on the same frames.
  const int material = std::stoi(worst.substr(9));
  const PixelTable fit_table = table_of(dir / "capture", kFitFrames, 0);
  nlohmann::json effect = named("material_offset");
  effect["material"] = material;
  const std::vector<Candidate> fits =
      fit_effects(fit_table, chain_with_effects({}), std::vector<nlohmann::json>{effect});
  ASSERT_EQ(fits.size(), 1u);
  ASSERT_EQ(fits[0].params.size(), 1u);  // the material is fixed
  const FittedParameter& offset = fits[0].params[0];
  std::printf("material_offset on material %d: offset_m %.5f [%.5f, %.5f], delta BIC %.0f\n", material, offset.value,
              offset.ci95_lo, offset.ci95_hi, fits[0].delta_bic);
  EXPECT_LE(offset.ci95_lo, PaintDepthBias::kBiasM);
  EXPECT_GE(offset.ci95_hi, PaintDepthBias::kBiasM);
  EXPECT_GT(fits[0].delta_bic, 100.0);
  expect_error_falls_to_the_generators(dir / "capture", fits[0].effect_json, "test_paint_depth_bias");
  fs::remove_all(dir);
}

TEST_F(OutOfLibrary, AFewWeakChannelsAreTracedToTheirBeamsThenWrittenFittedAndTheErrorFalls) {
  const fs::path dir = temp_dir("weak");
  record_hidden("test_weak_channels", dir / "capture");
  const Report report = compare_diagnose(dir / "capture", dir / "report");
  ASSERT_EQ(report.code, 0);
  const auto& diagnosis = report.json.at("diagnosis");
  EXPECT_EQ(diagnosis.at("verdict"), "missing effect");
  const nlohmann::json* detection = unexplained(report.json, "detection");
  ASSERT_NE(detection, nullptr) << diagnosis.dump(1);
  std::printf("%s\n", detection->at("sentence").get<std::string>().c_str());
  ASSERT_FALSE(detection->at("features").empty());
  EXPECT_EQ(detection->at("features")[0], "beam") << detection->at("sentence");
  for (const char* other : {"range", "reflectivity", "azimuth", "time"}) {
    EXPECT_TRUE(contains(detection->at("not_features"), other)) << other << ": " << detection->at("sentence");
  }
  // The worst bins are the weak beams themselves.
  std::vector<int> beams;
  for (const auto& region : detection->at("regions")) {
    const std::string text = region;
    ASSERT_EQ(text.rfind("beam ", 0), 0u) << text;
    beams.push_back(std::stoi(text.substr(5)));
  }
  ASSERT_FALSE(beams.empty());
  for (const int b : beams) EXPECT_TRUE(b >= 20 && b <= 23) << b;
  EXPECT_NEAR(detection->at("size").get<double>(), WeakChannels::kLoss, 0.05);

  // The user's effect, from the sentence and the per-beam bins of the report: beams 20-23.
  const PixelTable fit_table = table_of(dir / "capture", kFitFrames, 0);
  nlohmann::json effect = named("beam_loss");
  effect["first_beam"] = 20;
  effect["last_beam"] = 23;
  effect["loss"] = 0.1;
  const std::vector<Candidate> fits =
      fit_effects(fit_table, chain_with_effects({}), std::vector<nlohmann::json>{effect});
  ASSERT_EQ(fits.size(), 1u);
  ASSERT_EQ(fits[0].params.size(), 1u);
  const FittedParameter& loss = fits[0].params[0];
  std::printf("beam_loss on beams 20-23: loss %.4f [%.4f, %.4f], delta BIC %.0f\n", loss.value, loss.ci95_lo,
              loss.ci95_hi, fits[0].delta_bic);
  // The fitted frames happen to lose 40.7 % of those returns (2.5 standard errors above 40 %; the
  // held-out frames lose 40.05 %), so the interval is held to twice its width.
  EXPECT_NEAR(loss.value, WeakChannels::kLoss, loss.ci95_hi - loss.ci95_lo);
  expect_error_falls_to_the_generators(dir / "capture", fits[0].effect_json, "test_weak_channels");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lidartwin::cli_out_of_library_test
