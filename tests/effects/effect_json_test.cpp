// Effects from JSON: errors name the source, path and range; round trips; the registry; every
// shipped profile's chain builds.
#include <map>

#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

namespace {
std::string error_of(const json& effects, const Location& at = {"profiles/os1-64.json", "/effects"}) {
  try {
    EffectChain::from_json(effects, at);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(EffectJson, ErrorsNameTheSourcePathAndRange) {
  json effects = json::array({{{"name", "radiometry"}}, {{"name", "range_quantization"}}, kLinearOs1});
  effects[2]["sigma0_m"] = -0.01;
  EXPECT_EQ(error_of(effects), "profiles/os1-64.json: /effects/2/sigma0_m: must be in [0, 1], got -0.01");

  effects[2]["sigma0_m"] = "1 cm";
  EXPECT_EQ(error_of(effects),
            "profiles/os1-64.json: /effects/2/sigma0_m: must be a number in [0, 1], got a string \"1 cm\"");

  effects[2].erase("sigma0_m");
  EXPECT_EQ(error_of(effects),
            "profiles/os1-64.json: /effects/2/sigma0_m: missing; range_noise_linear needs it, a number in [0, 1]");

  effects[2]["sigma0_m"] = 0.01;
  effects[2]["sigma_m"] = 0.01;
  EXPECT_EQ(error_of(effects),
            "profiles/os1-64.json: /effects/2/sigma_m: unknown key of range_noise_linear; "
            "allowed keys here: name, sigma0_m, sigma_max_m, range_max_m");

  EXPECT_EQ(error_of(json::array({{{"name", "range_noise_gaussian"}}})),
            "profiles/os1-64.json: /effects/0/name: unknown effect \"range_noise_gaussian\"; registered effects: "
            "beam_calibration, drift, dropout, false_alarms, fog, halo, incidence, mixed_pixels, radiometry, "
            "range_limits, range_noise_linear, "
            "range_noise_piecewise, range_quantization, range_walk, shot_noise, signal_outliers, signal_precision, "
            "vibration, "
            "window");
  EXPECT_TRUE(
      error_of(json::array({{{"sigma0_m", 0.01}}}))
          .starts_with("profiles/os1-64.json: /effects/0/name: missing; registered effects: beam_calibration,"));
  EXPECT_EQ(error_of(json::object()),
            "profiles/os1-64.json: /effects: must be an array of effects [{\"name\": ...}, ...], got an object");
  EXPECT_EQ(error_of(json::array({{{"name", "range_limits"}, {"min_m", 5}, {"max_m", 1}}})),
            "profiles/os1-64.json: /effects/0/max_m: must be greater than min_m (5), got 1");
  EXPECT_EQ(error_of(json::array({{{"name", "range_quantization"}, {"step_m", true}}}), Location{"file.json", ""}),
            "file.json: /0/step_m: must be a number in [0, 1], got a boolean true");
}

TEST(EffectJson, PiecewiseKnotErrors) {
  const auto knots_error = [](const char* knots) {
    return error_of(json::array({piecewise(json::parse(knots))}), Location{"os0.json", "/effects"});
  };
  EXPECT_EQ(knots_error("[[1, 0.01]]"), "os0.json: /effects/0/points_m: needs at least 2 knots [range_m, sigma_m]");
  EXPECT_EQ(knots_error("[[1, 0.01], [1, 0.02]]"),
            "os0.json: /effects/0/points_m/1/0: must be greater than the previous knot's range 1, got 1");
  EXPECT_EQ(knots_error("[[1, 0.01], [2, 0]]"), "os0.json: /effects/0/points_m/1/1: must be in [1e-06, 10], got 0");
  EXPECT_EQ(knots_error("[[1, 0.01], [2]]"), "os0.json: /effects/0/points_m/1: must be [range_m, sigma_m]");
  EXPECT_EQ(error_of(json::array({{{"name", "range_noise_piecewise"}}}), Location{"os0.json", "/effects"}),
            "os0.json: /effects/0/points_m: missing; range_noise_piecewise needs [[range_m, sigma_m], ...]");
}

TEST(EffectJson, WithParametersChecksBounds) {
  const EffectChain chain = chain_of(json::array({kLinearOs1}));
  const std::vector<double> bad{0.01, 0.15, 0.0};
  try {
    (void)chain.effects()[0]->with_parameters(bad);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "range_noise_linear: /range_max_m: must be in [0.1, 10000], got 0");
  }
  const std::vector<double> too_few{0.01};
  EXPECT_THROW((void)chain.effects()[0]->with_parameters(too_few), InputError);
}

TEST(EffectJson, RoundTripsEveryEffect) {
  const json effects = json::array({{{"name", "radiometry"}, {"gain_photons_m2", 2e5}},
                                    piecewise(kKnotsOs1),
                                    kLinearOs0,
                                    {{"name", "dropout"}, {"width", 0.5}},
                                    {{"name", "range_limits"}, {"min_m", 0.5}, {"max_m", 45.0}},
                                    {{"name", "range_quantization"}, {"step_m", 0.001}}});
  const EffectChain chain = chain_of(effects);
  const json out = chain.to_json();
  EXPECT_EQ(out[1]["points_m"], kKnotsOs1);
  EXPECT_EQ(out[0]["gain_photons_m2"], 2e5);
  EXPECT_EQ(out[0]["overlap_range_m"], 8.0);  // defaults are written out
  EXPECT_EQ(chain_of(out).to_json(), out);
  // The piecewise sigmas are fittable, the knot ranges are structure.
  const auto parameters = chain.effects()[1]->parameters();
  ASSERT_EQ(parameters.size(), 16u);
  EXPECT_EQ(parameters[0].name, "points_m/0/0");
  EXPECT_TRUE(parameters[0].fixed);
  EXPECT_FALSE(parameters[1].fixed);
}

TEST(EffectRegistry, ListsBuiltInsAndAcceptsNewEffects) {
  const auto names = lidartwin::registered_effects();
  for (const char* name :
       {"radiometry", "range_noise_linear", "range_noise_piecewise", "range_limits", "range_quantization", "dropout"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  }
  lidartwin::register_effect("test_alias_of_quantization", [](const json& params, const Location& at) {
    json copy = params;
    copy["name"] = "range_quantization";
    return EffectChain::from_json(json::array({copy}), at).effects()[0]->with_parameters(std::vector<double>{0.001});
  });
  EXPECT_EQ(chain_of(json::array({{{"name", "test_alias_of_quantization"}}})).effects().size(), 1u);
  EXPECT_EQ(lidartwin::effect_catalogue("test_alias_of_quantization"), "");
}

// Reports name the physics by lidar-physics.md's catalogue id.
TEST(EffectRegistry, EveryBuiltInRangeEffectCarriesItsCatalogueId) {
  const std::map<std::string, std::string> expected{{"range_noise_linear", "E1"},
                                                    {"range_noise_piecewise", "E1"},
                                                    {"signal_precision", "E2"},
                                                    {"signal_outliers", "E2"},
                                                    {"range_walk", "E3"},
                                                    {"incidence", "E4"},
                                                    {"dropout", "E5"},
                                                    {"mixed_pixels", "E6"},
                                                    {"halo", "E8"},
                                                    {"range_quantization", "E9"},
                                                    {"beam_calibration", "E10"},
                                                    {"vibration", "E11"},
                                                    {"drift", "E12"},
                                                    {"fog", "E13"},
                                                    {"false_alarms", "E14"},
                                                    {"range_limits", "E16"},
                                                    {"window", "E16"},
                                                    {"radiometry", ""},
                                                    {"shot_noise", ""}};
  for (const std::string& name : lidartwin::registered_effects()) {
    if (name.starts_with("test_")) continue;  // registered by another test in this binary
    ASSERT_TRUE(expected.count(name)) << name << " is registered but this test does not know its catalogue id";
    EXPECT_EQ(lidartwin::effect_catalogue(name), expected.at(name)) << name;
  }
  EXPECT_EQ(lidartwin::effect_catalogue("no_such_effect"), std::nullopt);
  lidartwin::register_effect(
      "test_fog", [](const json&, const Location&) -> std::unique_ptr<lidartwin::Effect> { return nullptr; }, "E13");
  EXPECT_EQ(lidartwin::effect_catalogue("test_fog"), "E13");
}

// ---- every profile's chain ----

TEST(Profiles, EveryEffectChainBuilds) {
  const std::filesystem::path dir = std::filesystem::path(LIDARTWIN_SOURCE_DIR) / "profiles";
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_directory(dir)) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.path().extension() == ".json") files.push_back(entry.path());
    }
  }
  ASSERT_FALSE(files.empty()) << "no profiles in " << dir << ": the shipped profiles are missing";
  std::sort(files.begin(), files.end());
  for (const auto& file : files) {
    SCOPED_TRACE(file.string());
    std::ifstream in(file);
    const json document = json::parse(in);
    ASSERT_TRUE(document.contains("effects")) << file;
    const Location at{"profiles/" + file.filename().string(), "/effects"};
    EffectChain chain;
    ASSERT_NO_THROW(chain = EffectChain::from_json(document.at("effects"), at));
    EXPECT_EQ(chain.effects().size(), document.at("effects").size());
    // A hit inside the profile's range is detected with some noise; no hit stays no return.
    const Prediction p = chain.predict(surface(10.0f, 0.5f), {});
    EXPECT_GT(p.p_detect, 0.5) << file;
    EXPECT_EQ(chain.predict(IdealReturn{}, {}).p_detect, 0.0) << file;
  }
}
