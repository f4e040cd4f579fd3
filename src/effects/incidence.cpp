// E4 (lidar-physics.md "Incidence-angle dependence of noise and bias"): on an oblique surface the
// beam footprint spans a range of depths, which broadens the return pulse and, depending on how
// the detector times it, shifts it. With the footprint's angular width gamma (beam divergence,
// FWHM, radians) and incidence theta:
//   variance += (r * tan(theta) * gamma / 2.355)^2      (Gaussian footprint: FWHM -> sigma)
//   bias     += kappa * r * tan(theta) * gamma          (kappa fitted; sign detector-dependent)
// Default divergence: 0.13 degrees, the OS1-64's (lidar-physics.md E4, from the datasheet [S1]);
// kappa defaults to 0 (no published value for Ouster). tan(theta) is capped at 20 (87 degrees):
// beyond it the footprint model is meaningless and the return is mostly gone anyway.
// saturation s >= 0 lets the footprint's depth saturate, tan(theta) becoming
//   tan(theta) / (1 + s tan(theta))      (about tan(theta) below 1/s, at most 1/s beyond it)
// [proposed, fitted on real captures]: on the real OS-1-128 and OS-2-128 samples the spread grows
// with incidence more slowly than r tan(theta) towards grazing (the footprint's far part, dimmer by
// r^-2 and cos, counts less in the detector's timing than its near part). s = 0, the default, is
// the footprint law above, and the law is nested in the saturating form, so a fit can test one
// against the other from s = 0.
#include <algorithm>
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

constexpr double kSigmaPerFwhm = 1.0 / 2.3548200450309493;  // 1 / (2 sqrt(2 ln 2))
constexpr float kMaxTan = 20.0f;
constexpr float kMinCos = 1.0f / 400.0f;  // below 1 / kMaxTan: the cap decides

struct IncidenceParameters {
  double divergence_rad = 0.13 * 3.141592653589793 / 180.0;
  double bias_factor = 0.0;
  double saturation = 0.0;  // 0: tan(theta) itself
};

class Incidence final : public TabledEffect<Incidence, IncidenceParameters> {
 public:
  using P = IncidenceParameters;
  static constexpr std::string_view kName = "incidence";
  static constexpr std::array<ParameterSpec<P>, 3> kSpecs{{
      {"divergence_rad", &P::divergence_rad, {0.0, 0.05}},
      {"bias_factor", &P::bias_factor, {-2.0, 2.0}},
      {"saturation", &P::saturation, {0.0, 10.0}},
  }};
  using TabledEffect::TabledEffect;

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    const ColumnStreams streams = column_streams(context);
    float* range = measured.range_m.data();
    for (const uint32_t beam : measured.listed_returns()) {
      if (range[beam] == 0.0f) continue;
      const double spread = footprint_m(ideal[beam]);
      const double shift = params().bias_factor * spread;
      range[beam] = static_cast<float>(static_cast<double>(range[beam]) + shift +
                                       spread * kSigmaPerFwhm * streams(beam).normal_ziggurat(0));
    }
  }

  bool adds_returns() const override { return false; }

  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    const double spread = footprint_m(ideal);
    prediction.bias_m += params().bias_factor * spread;
    prediction.variance_m2 += (spread * kSigmaPerFwhm) * (spread * kSigmaPerFwhm);
  }

 private:
  // r * tan(theta) * gamma: the depth the footprint spans (FWHM). tan(theta) in float (the cosine
  // is a float): a double square root and division per return took the divider 15 cycles, more
  // than the rest of the effect (perf of `record` from the ground pose).
  double footprint_m(const IdealReturn& ideal) const {
    const float c = std::clamp(ideal.cos_incidence, kMinCos, 1.0f);
    float tan_theta = std::min(std::sqrt(1.0f - c * c) / c, kMaxTan);
    if (const auto s = static_cast<float>(params().saturation); s > 0.0f)
      tan_theta = tan_theta / (1.0f + s * tan_theta);
    return static_cast<double>(ideal.range_m * tan_theta) * params().divergence_rad;
  }
};

}  // namespace

std::unique_ptr<Effect> make_incidence(const nlohmann::json& params, const Location& at) {
  return Incidence::create(params, at);
}

// A profile's incidence refits its footprint's saturation too (from the law, s = 0, in which the
// saturating form is nested): real captures ask for it (docs/compare-report.md, "A footprint that
// saturates"). The search's candidate keeps the law, whose form the simulated captures follow, and
// one parameter fewer. Without a scene the surface's tilt is unknown.
EffectCard incidence_card() {
  return {.catalogue = "E4",
          .candidate = true,
          .fit = {{"divergence_rad", 0.002, 0.001}, {"bias_factor", 0.0, 0.2}},
          .refit_also = {{"saturation", 0.1, 0.1}},
          .seen_against_temporal_mean = false};
}

}  // namespace lidartwin::effects_detail
