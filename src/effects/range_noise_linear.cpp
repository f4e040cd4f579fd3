// E1(a), baseline B0 (lidar-physics.md section 0; Tejero et al., Section III): zero-mean Gaussian
// range noise along the beam whose standard deviation grows linearly with the true range,
//   sigma(r) = sigma0 + (sigma_max - sigma0) * r / r_max.
// The paper defines sigma only up to r_max (45 m OS0, 100 m OS1); beyond it we keep extrapolating
// the same line, so a profile whose range limit exceeds r_max still gets a continuous law.
#include "effects/builtin_effects.h"
#include "effects/gaussian_range_noise.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct LinearNoiseParameters {
  double sigma0_m = 0.0;     // sigma at r = 0 (paper: 1 cm for OS0 and OS1)
  double sigma_max_m = 0.0;  // sigma at r_max (paper: 10 cm OS0, 15 cm OS1)
  double range_max_m = 1.0;  // r_max (paper: 45 m OS0, 100 m OS1)
};

class RangeNoiseLinear final
    : public GaussianRangeNoise<RangeNoiseLinear, TabledEffect<RangeNoiseLinear, LinearNoiseParameters>> {
 public:
  using P = LinearNoiseParameters;
  static constexpr std::string_view kName = "range_noise_linear";
  static constexpr std::array<ParameterSpec<P>, 3> kSpecs{{
      {"sigma0_m", &P::sigma0_m, {0.0, 1.0}, true},
      {"sigma_max_m", &P::sigma_max_m, {0.0, 10.0}, true},
      {"range_max_m", &P::range_max_m, {0.1, 10000.0}, true},
  }};

  explicit RangeNoiseLinear(const P& p) : GaussianRangeNoise(p), slope_((p.sigma_max_m - p.sigma0_m) / p.range_max_m) {}

  // sigma(r) of the true range; clamped at 0 in case sigma_max < sigma0 extrapolates below zero.
  double sigma(float range_m) const { return std::max(0.0, params().sigma0_m + slope_ * static_cast<double>(range_m)); }

 private:
  double slope_;
};

}  // namespace

std::unique_ptr<Effect> make_range_noise_linear(const nlohmann::json& params, const Location& at) {
  return RangeNoiseLinear::create(params, at);
}

// The range noise's forms are the analysis' noise laws (noise_laws.h), refitted only on request
// (compare --refit-noise), never added: a profile has one.
EffectCard range_noise_linear_card() { return {.catalogue = "E1"}; }

}  // namespace lidartwin::effects_detail
