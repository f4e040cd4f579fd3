#pragma once
// Where the model fails (lidar-physics.md 3.2-3.3): every pixel scored by the chain's own predicted
// distribution, then binned over each feature and over pairs of features; per bin the measured
// and predicted bias, spread, detection rate and outlier rate, the misfit split into those parts,
// and a test of each, corrected for the number of tests. The failing bins, worst first, each in a
// sentence a user understands.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "lidartwin/analysis/pixel_table.h"

namespace lidartwin {

// Per-pixel scores, parallel to the PixelTable.
struct PixelScores {
  std::vector<float> nll;
  std::vector<float> z;    // standardized range residual, returns only (0 otherwise)
  std::vector<float> pit;  // randomized PIT, returns only (-1 otherwise)
  std::vector<uint8_t> impossible;
  std::vector<float> mean_m;        // returns: the predicted mean and sd of the measured range
  std::vector<float> sd_m;          // (window-truncated Gaussian component)
  std::vector<float> nll_expected;  // mean and variance of the NLL if the model were true
  std::vector<float> nll_variance;
};
PixelScores score_pixels(const PixelTable& table, uint64_t seed = 0, WorkerPool* pool = nullptr);
// The same into `out`, whose arrays are reused (no allocation when it scored a table of this size).
void score_pixels(const PixelTable& table, uint64_t seed, WorkerPool* pool, PixelScores& out);

// A region of feature space: feature name (compare vocabulary: range, incidence, reflectivity,
// signal, near_ir, beam, azimuth, time, edge, material, retro) -> [lo, hi].
using Region = std::vector<std::pair<std::string, std::array<double, 2>>>;

struct BinMisfit {
  Region region;
  size_t pixels = 0;   // pixels whose beam meets a surface in the scene
  size_t returns = 0;  // of those, measured returns
  size_t inliers = 0;  // returns within 5 sigma
  double detection_measured = 0.0, detection_predicted = 0.0;
  double bias_measured_m = 0.0, bias_predicted_m = 0.0;      // mean (range - ideal), inliers
  double spread_measured_m = 0.0, spread_predicted_m = 0.0;  // std of (range - ideal - bias); rms sigma
  double spread_ratio = 1.0;                                 // std of z over what the model expects
  double outliers_measured = 0.0, outliers_predicted = 0.0;  // fraction of returns beyond 5 sigma
  double misfit_bias = 0.0, misfit_spread = 0.0, misfit_detection = 0.0, misfit_outliers = 0.0;  // nats in the bin
  double nll = 0.0, nll_expected = 0.0;                                                          // summed over the bin
  // Corrected p-values (Bonferroni over every test made); 1 where the bin is too small to test.
  double p_bias = 1.0, p_spread = 1.0, p_detection = 1.0, p_outliers = 1.0;
};

struct FailingRegion {
  std::string quantity;  // bias, spread, detection, outliers
  Region region;
  double measured = 0.0;  // bias and spread in m, detection and outliers as fractions
  double predicted = 0.0;
  size_t pixels = 0;
  double p_value = 1.0;           // corrected
  double misfit_nats = 0.0;       // the bin's share of the NLL excess in this quantity (KL x pixels)
  double misfit_per_pixel = 0.0;  // the same per pixel: how strongly the model fails there (ranks regions)
  std::string sentence;
};

struct MisfitSummary {
  size_t frames = 0;
  size_t pixels = 0;  // every scored pixel (returns, misses, beams into the void)
  size_t returns = 0;
  double nll_per_pixel = 0.0;
  double nll_expected = 0.0;                                   // per pixel, if the model were true
  double nll_se = 0.0;                                         // standard error of nll_per_pixel under the model
  double detection_measured = 0.0, detection_predicted = 0.0;  // over pixels that meet a surface
  size_t unexpected_returns = 0;  // returns where the model gives (almost) none: no surface there, or out of reach
  size_t impossible_misses = 0;   // misses where the model is certain of a return
  double z_mean = 0.0, z_std = 0.0;
  std::vector<double> pit_histogram;  // 20 bins, fractions of returns
  double pit_uniformity_p = 1.0;      // chi-square test of the histogram against uniform
  size_t tests = 0;                   // tests the correction counted
};

// What a failing quantity's misfit follows once correlated features are partialled out
// (unexplained.h's forward selection): the features it follows, strongest first, and those tested
// and not followed given them, which only ride along (beams that see more depth edges than others,
// when the misfit is at the edges).
struct MisfitCause {
  std::string quantity;
  std::vector<std::string> follows;
  std::vector<std::string> rides_along;
};

struct Misfit {
  MisfitSummary summary;
  std::vector<BinMisfit> bins;  // every populated bin of every binning
  // p < alpha after correction, worst first: by misfit per pixel, so a narrow band where the model
  // is far off ranks above a broad region that only averages it.
  std::vector<FailingRegion> failing;
  // Filled by find_causes (empty: the runs are ranked by their bins alone).
  std::vector<MisfitCause> causes;
};

struct MisfitOptions {
  double alpha = 0.01;  // significance level after the correction
};
// Without a scene (PixelTable::reference) the features that need its surfaces are not binned
// (static mode: incidence, material, retro, edge; map mode: material, retro, edge), a temporal
// mean's bias is not tested (it is the data's own), nor map mode's detection (returns only).
Misfit find_misfit(const PixelTable& table, const PixelScores& scores, size_t frames, const MisfitOptions& options);

// "range 20-35 m, incidence 60-75°"
std::string describe(const Region& region);

}  // namespace lidartwin
