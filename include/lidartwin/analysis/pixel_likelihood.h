#pragma once
// How likely one measured pixel is under the effect chain's prediction (lidar-physics.md 3.5): the
// detection term, and for a return the interval probability of its range bin under the truncated
// Gaussian (with an edge partner's and a wider tail's components) mixed with a uniform outlier
// component. Measured ranges are integers of the wire's step
// (1 mm, or 8 mm for RNG15), so every likelihood here is a probability, never a density: the NLLs of
// pixels, bins and profiles add up and compare on one scale.
#include <span>

#include "lidartwin/effects/measurement.h"

namespace lidartwin {

// What the analysis needs to score a pixel: the chain's prediction and the step of the range bins.
struct RangeModel {
  double mean_m = 0.0;   // ideal range + predicted bias
  double sigma_m = 0.0;  // > 0
  double p_detect = 0.0;
  double outlier_mix = 0.0;
  double window_min_m = 0.0;
  double window_max_m = 0.0;  // finite: the cast's reach when the chain sets no limit
  double step_m = 0.001;      // the measured range's bin width
  double partner_mix = 0.0;   // E6, E8: this share of the Gaussian lies partner_offset_m away,
  double partner_offset_m = 0.0;
  double partner_sigma_m = 0.0;  // with this sigma (0: sigma_m)
  double partner_sigma() const { return partner_sigma_m > 0.0 ? partner_sigma_m : sigma_m; }
  double tail_mix = 0.0;  // E2's tails: this share of the pixel's own returns is N(mean_m, tail_sigma_m^2)
  double tail_sigma_m = 0.0;
};

// The chain's prediction for an ideal return at ideal_range_m, on a wire with the given range step.
// Unlimited windows end at reach_m (where the cast stopped looking).
RangeModel range_model(const Prediction& prediction, double ideal_range_m, double wire_step_m, double reach_m);

// A probability this small stands for "the model says this cannot happen" (a return where the
// scene has no surface, a miss where detection is certain), so one such pixel costs a finite,
// visible 13.8 nats instead of infinity.
inline constexpr double kImpossible = 1e-6;

struct PixelScore {
  double nll = 0.0;  // -ln P(what was measured)
  // (measured - mean) / sd of the Gaussian component truncated to the window, returns only: a
  // return near a range limit is drawn from the part of the Gaussian inside it, whose mean and
  // spread differ from the untruncated ones.
  double z = 0.0;
  double mean_m = 0.0;  // that mean and sd
  double sd_m = 0.0;
  double pit = 0.5;         // randomized interval PIT of the range, returns only (uniform if the model is right)
  bool impossible = false;  // the model gave the measurement (almost) no probability
};

// Of the detected returns, the share from the edge partner's surface (E6): partner_mix weighted by
// the two components' mass inside the window.
double partner_share(const RangeModel& model);

// A return at measured_range_m (a multiple of step_m), or a miss (measured_range_m == 0).
// pit_draw in [0, 1) spreads the PIT across the measured range bin (lidar-physics.md 3.2).
PixelScore score_pixel(const RangeModel& model, double measured_range_m, double pit_draw);
// score_pixel's nll alone (what the fits evaluate), without the moments and the PIT.
double pixel_nll(const RangeModel& model, double measured_range_m);
// pixel_nll of each model and measured range (out[i] for models[i]), the common case's returns
// many at a time (SIMD, the same bits on every Highway target): the same values as pixel_nll.
void pixel_nlls(std::span<const RangeModel> models, std::span<const double> measured_range_m, std::span<double> out);

// The mean and variance of the NLL a pixel would have if the model were true: summed over pixels,
// they say what NLL to expect and how far from it the measured NLL may fall by chance.
struct NllMoments {
  double mean = 0.0;
  double variance = 0.0;
};
NllMoments expected_nll(const RangeModel& model);

// Standard normal CDF and the probability of [a, b] under it, accurate in both tails.
double normal_cdf(double x);
double normal_interval(double a, double b);
// Chi-square CDF by the Wilson-Hilferty cube-root normal approximation (good for dof >= 10 and
// fine for ranking below that): the tests of the bins' spread, the PIT and the diagnosis' LRT.
double chi2_cdf(double x, double dof);

}  // namespace lidartwin
