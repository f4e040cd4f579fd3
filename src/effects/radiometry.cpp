// The signal, reflectivity and near-infrared channels (lidar-physics.md section 2.2):
//   rho_app = rho cos(theta) + k_s max(0, cos 2theta)^n    (Lambertian + monostatic Phong lobe, E7)
//           = rho_retro                                   (retroreflector: angle-insensitive)
//   S       = gain * K * rho_app * g(r) * exp(-2 alpha r) / r^2,   g(r) = 1 / (1 + (r0/r)^p)
// g is the near-field overlap (-> 1 far away, E16), alpha the atmospheric extinction (E13), gain
// the column context's signal multiplier and mode integration (E18). Defaults are fitted to the
// OS1-32 FW 2.1 frame of Appendix A: median S r^2 at reflectivity 8-12 (rho_app ~ 0.1) of 244,
// 3369, 8238, 13486, 13842 over 2-4, 4-8, 8-16, 16-32, 32-64 m give K = 1.38e5 photons m^2 (the
// far-field level) and, by least squares in log S r^2, r0 = 8.0 m, p = 3.8.
// REFLECTIVITY is the firmware's inverse of S (so it reports rho_app): 100 rho_app up to 100 %,
// then a logarithmic band 101-255 for retroreflectors, rho_app = reflectivity_255 mapping to 255
// (section 2.1: two-band scheme well supported, its log slope unverified: a fitted parameter).
// NEAR_IR is the ambient light the surface reflects, B = ambient * rho (section 2.2 step 3); the
// signal gain does not scale it (the laser's multiplier adds no sunlight).
// The channels are expected values, without shot noise: effects that depend on the signal
// (dropout, E5) then see in simulate exactly what predict reports, and simulate/predict agree.
#include <bit>
#include <cmath>
#include <cstdint>

#include "effects/builtin_effects.h"
#include "effects/log_spaced_table.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct RadiometryParameters {
  double gain_photons_m2 = 1.38e5;  // K: far-field S r^2 / rho_app
  double overlap_range_m = 8.0;     // r0 of g(r); 0 = no near-field roll-off
  double overlap_exponent = 3.8;    // p of g(r)
  double attenuation_per_m = 0.0;   // alpha (E13); 0 = clear air
  double specular_exponent = 20.0;  // n of the Phong lobe, used where the material has specular > 0
  double retro_reflectance = 20.0;  // rho_app of a retroreflective hit (signal ~6000 vs <1000, [S36])
  double reflectivity_255 = 100.0;  // rho_app reported as 255
  double ambient_photons = 100.0;   // NEAR_IR of a rho = 1 surface (no measured level yet: per scene)
  double sky_photons = 0.0;         // NEAR_IR where the beam hits nothing
};

class Radiometry final : public TabledEffect<Radiometry, RadiometryParameters> {
 public:
  using P = RadiometryParameters;
  static constexpr std::string_view kName = "radiometry";
  static constexpr std::array<ParameterSpec<P>, 9> kSpecs{{
      {"gain_photons_m2", &P::gain_photons_m2, {1.0, 1e9}},
      {"overlap_range_m", &P::overlap_range_m, {0.0, 200.0}},
      {"overlap_exponent", &P::overlap_exponent, {0.5, 12.0}},
      {"attenuation_per_m", &P::attenuation_per_m, {0.0, 1.0}},
      {"specular_exponent", &P::specular_exponent, {1.0, 10000.0}},
      {"retro_reflectance", &P::retro_reflectance, {1.0, 10000.0}},
      {"reflectivity_255", &P::reflectivity_255, {1.01, 1e5}},
      {"ambient_photons", &P::ambient_photons, {0.0, 65535.0}},
      {"sky_photons", &P::sky_photons, {0.0, 65535.0}},
  }};

  explicit Radiometry(const P& p)
      : TabledEffect(p),
        range_factor_([&p](double r) {
          const double overlap =
              p.overlap_range_m > 0.0 ? 1.0 / (1.0 + std::pow(p.overlap_range_m / r, p.overlap_exponent)) : 1.0;
          return overlap * std::exp(-2.0 * p.attenuation_per_m * r) / (r * r);
        }),
        log_band_scale_(static_cast<float>(155.0 / std::log(p.reflectivity_255))) {}

  float apparent_reflectance(const IdealReturn& in) const {
    if (in.retroreflective) return static_cast<float>(params().retro_reflectance);
    float rho = in.reflectivity * in.cos_incidence;
    if (in.specular > 0.0f) {
      const float cos_2theta = 2.0f * in.cos_incidence * in.cos_incidence - 1.0f;
      if (cos_2theta > 0.0f) rho += in.specular * std::pow(cos_2theta, static_cast<float>(params().specular_exponent));
    }
    return rho;
  }
  float reflectivity_byte(float rho_app) const {
    if (rho_app <= 1.0f) return 100.0f * rho_app;
    return std::min(255.0f, 100.0f + log_band_scale_ * std::log(rho_app));
  }
  float near_ir(const IdealReturn& in) const {
    return in.hit() ? static_cast<float>(params().ambient_photons) * in.reflectivity
                    : static_cast<float>(params().sky_photons);
  }
  float column_gain(const ColumnContext& context) const {
    return static_cast<float>(params().gain_photons_m2) * context.signal_gain;
  }

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    const float gain = column_gain(context);
    // near_ir() for every beam as a select on bit patterns, not a branch (hits and sky interleave
    // in a column), with the parameters in registers: the stores may alias them otherwise.
    const auto ambient = std::bit_cast<uint32_t>(static_cast<float>(params().ambient_photons));
    const auto sky = std::bit_cast<uint32_t>(static_cast<float>(params().sky_photons));
    float* __restrict near_ir = measured.near_ir_photons.data();
    for (size_t beam = 0; beam < ideal.size(); ++beam) {
      const IdealReturn& in = ideal[beam];
      const uint32_t hit = 0u - static_cast<uint32_t>(std::bit_cast<int32_t>(in.range_m) > 0);  // hit(): range > 0
      const auto lit = std::bit_cast<uint32_t>(std::bit_cast<float>(ambient) * in.reflectivity);
      near_ir[beam] = std::bit_cast<float>((lit & hit) | (sky & ~hit));
    }
    for (const uint32_t beam : measured.listed_returns()) {
      const IdealReturn& in = ideal[beam];
      if (!in.hit() || measured.range_m[beam] == 0.0f) continue;  // no return: no signal, no reflectivity
      const float rho_app = apparent_reflectance(in);
      measured.signal_photons[beam] = gain * rho_app * range_factor_(in.range_m);
      measured.reflectivity[beam] = reflectivity_byte(rho_app);
    }
  }

  bool adds_returns() const override { return false; }

  void predict(const IdealReturn& in, const ColumnContext& context, Prediction& prediction) const override {
    prediction.near_ir_photons = static_cast<double>(near_ir(in));
    if (!in.hit()) return;
    prediction.signal_photons =
        static_cast<double>(column_gain(context) * apparent_reflectance(in) * range_factor_(in.range_m));
  }

 private:
  LogSpacedTable range_factor_;  // g(r) exp(-2 alpha r) / r^2
  float log_band_scale_;
};

}  // namespace

std::unique_ptr<Effect> make_radiometry(const nlohmann::json& params, const Location& at) {
  return Radiometry::create(params, at);
}

// No catalogue id: lidar-physics.md 2.2's channels, not a range error. The analysis refits it by
// its own closed forms (refit_radiometry), not as a candidate.
EffectCard radiometry_card() {
  return {.catalogue = "", .note = "no catalogue id: lidar-physics.md 2.2, the expected SIGNAL and NEAR_IR"};
}

}  // namespace lidartwin::effects_detail
