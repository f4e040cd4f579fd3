#pragma once
// What `compare` writes: DIR/report.json (schema: docs/compare-report.md) and DIR/pixels.npz.
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/pixel_table.h"

namespace lidartwin {

inline constexpr const char* kCompareReportSchema = "lidartwin.compare/1";

// One profile's row of the waterfall (lidar-physics.md 3.6): the error measures that fall as the
// model improves, on the same pixels.
struct WaterfallStep {
  std::string profile;
  double nll_per_pixel = 0.0, nll_expected = 0.0, nll_se = 0.0;
  double bias_rms_m = 0.0;           // RMS over single-feature bins of (measured - predicted) bias
  double spread_ratio_median = 1.0;  // median over those bins
  double detection_log_loss = 0.0;   // per pixel that meets a surface
  size_t failing = 0;
};
WaterfallStep waterfall_step(const std::string& profile, const PixelTable& table, const Misfit& misfit);
nlohmann::json waterfall_json(const std::vector<WaterfallStep>& steps);

// inputs: what was compared (paths, pose offset, profile name…), copied into the report as given.
nlohmann::json compare_report(const Misfit& misfit, const nlohmann::json& inputs, double alpha);

// Every column of the table and of the scores, one array each (names: docs/compare-report.md).
void write_pixels_npz(const std::filesystem::path& path, const PixelTable& table, const PixelScores& scores);

}  // namespace lidartwin
