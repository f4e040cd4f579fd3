#pragma once
// What `compare` writes: DIR/report.json (schema: docs/compare-report.md) and DIR/pixels.npz.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/analysis/diagnosis.h"
#include "lidartwin/analysis/frame_registration.h"
#include "lidartwin/analysis/map_table.h"
#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/pixel_table.h"
#include "lidartwin/analysis/pose_refinement.h"

namespace lidartwin {

inline constexpr const char* kCompareReportSchema = "lidartwin.compare/1";

// A failing region as the report leads with it (report.json's "failing_runs"): neighbouring bins
// of one feature that fail in the same quantity the same way merged into one run ("beams 40–44"),
// runs ranked by the misfit their feature explains (in total, not per pixel, so a broad failure
// outranks a narrow bin; and about the rest of the feature, so that a misfit every bin shares
// alike, as every material does a drift's, does not name a bin first), materials named as the
// scene names them.
struct FailingRun {
  std::string quantity;
  Region region;  // the run's span
  size_t bins = 1;
  size_t pixels = 0;
  double misfit_nats = 0.0;
  double localized_nats = 0.0;  // its bins' misfit about their binning's mean deviation (failing_runs.cpp)
  double p_value = 1.0;         // its bins' smallest (corrected)
  std::string where;            // "beams 40–44", "material wall_grey (48)"; "everywhere (beams 0–127)" for a
                                // run over every tested bin of its feature
  bool everywhere = false;      // the run spans every tested bin of its feature: no place, the whole feature
  std::string rides_along;      // the feature the quantity's misfit follows, which this run's only rides
                                // along with (Misfit::causes); empty otherwise
  std::string trend;            // how a run of 3 or more bins changes along them: "falling with time", "most at
                                // range 13–20 m"; empty when it does not, or not clearly
  std::string sentence;
};
// material_names: by material id; empty or "" where the scene names none.
std::vector<FailingRun> failing_runs(const Misfit& misfit, const std::vector<std::string>& material_names);

// One profile's row of the waterfall (lidar-physics.md 3.6): the error measures that fall as the
// model improves, on the same pixels.
struct WaterfallStep {
  std::string profile;
  double nll_per_pixel = 0.0, nll_expected = 0.0, nll_se = 0.0;
  double bias_rms_m = 0.0;           // RMS over single-feature bins of (measured - predicted) bias
  double spread_ratio_median = 1.0;  // median over those bins
  double detection_log_loss = 0.0;   // per pixel that meets a surface
  size_t failing = 0;
  // The NLL's excess over its expectation (nats per pixel of the capture) summed over the range x
  // reflectivity bins where it is negative (the model too wide or too unsure there) and where it is
  // positive (too narrow or too sure): the two parts the headline's average lets cancel.
  double excess_below = 0.0, excess_above = 0.0;
  std::vector<FailingRun> failing_runs;  // its own, largest misfit first (report.html's table)
  // Beside the step before it, where the NLL and the excess over the profile's own expectation
  // move apart (a better fit whose excess grows): why; empty otherwise.
  std::string note;
};
// material_names: as failing_runs takes them.
WaterfallStep waterfall_step(const std::string& profile, const PixelTable& table, const Misfit& misfit,
                             const std::vector<std::string>& material_names = {});
// Where `after` fits better than `before` but its excess moved away from 0, or worse while nearer
// 0: why, with both steps' parts of the excess; empty otherwise.
std::string excess_note(const WaterfallStep& before, const WaterfallStep& after);
// Each step's note against the one before it (WaterfallStep::note).
void note_waterfall(std::vector<WaterfallStep>& steps);
nlohmann::json waterfall_json(const std::vector<WaterfallStep>& steps);

// The standardized range residuals (z) of the returns in one band of ideal range, counted in
// kResidualBins bins over [-6, 6], the outer ones taking what lies beyond: report.html's residual
// histograms, from report.json alone (pixels.npz is written only on request).
struct ResidualHistogram {
  static constexpr int kBins = 120;
  double lo_m = 0.0, hi_m = 0.0;
  size_t returns = 0;
  std::vector<uint32_t> counts;
};
// The bands 0-5, 5-13, 13-35 m and beyond; returns the model does not rule out.
std::vector<ResidualHistogram> residual_histograms(const PixelTable& table, const PixelScores& scores);

// The misfit as a range image (report.json's "range_image"): beam x azimuth sector, one image per
// quantity that fails anywhere, so a user sees where on the sensor's own picture it lies. Per cell:
// bias, the mean z of the inliers (|z| <= 5); spread, their sd (1 where the model is right);
// detection, the measured minus the predicted return rate of the pixels that meet a surface;
// outliers, the share of returns beyond 5 sigma. NaN where a cell has no such pixel.
struct RangeImage {
  static constexpr int kAzimuthBins = 128;
  int beams = 0;
  std::vector<uint32_t> pixels;  // beam-major, beams x kAzimuthBins
  std::vector<std::pair<std::string, std::vector<float>>> quantities;
};
RangeImage range_image(const PixelTable& table, const PixelScores& scores, const Misfit& misfit);

// What was compared: report.json's "inputs".
struct CompareInputs {
  std::string capture, metadata, scene, pose;  // as given (a pose found beside a record directory's capture)
  bool static_mode = false;
  bool map_mode = false;
  std::string profile;  // the profile the report is of (a waterfall's last)
  double time_offset_s = 0.0;
  size_t frames = 0;  // scored
  size_t skipped_frames = 0;
  std::string lidar_mode, udp_profile_lidar;
  std::vector<std::string> missing_fields;        // of the profile, absent from an OSF recording
  size_t columns_not_received = 0;                // of the frames read: absent, left out (not misses)
  uint64_t seed = 0;                              // of the randomised PIT
  std::optional<PoseRefinement> pose_refinement;  // --refine-pose
  std::optional<FrameRegistration> registration;  // --map without --pose
  std::optional<MapExclusions> map;               // --map: what was compared and what left out
  bool map_within_frame = false;                  // --map's references from each frame's own returns
  std::vector<std::string> material_names;        // the scene's, by material id (Embree geometry)
};

// Everything `compare` found; report.json is this, written by report_json alone.
struct CompareResult {
  CompareInputs inputs;
  Misfit misfit;  // of the report's profile
  double alpha = 0.01;
  std::vector<WaterfallStep> waterfall;  // every profile's row; written when there are several
  std::optional<Diagnosis> diagnosis;    // --diagnose
  std::vector<ResidualHistogram> residuals;
  std::optional<RangeImage> image;
  // The command that applies the diagnosis (`lidartwin fit ... --add ...`); empty: nothing to apply.
  std::string next_command;
  // The report's profile: its product line, and how far its units are known to differ
  // (SensorProfile::unit_range_spread, 0: unknown, and where that is known from).
  std::string prod_line;
  double unit_range_spread = 0.0;
  std::string unit_to_unit_source;
};
nlohmann::json report_json(const CompareResult& result);

// What is wrong and what to do next, in one sentence: where the misfit lies (the two quantities
// that carry most of it, each with its worst region), what --diagnose found, and the next command;
// and, where the range spread is below the model's nearly everywhere, that this unit's noise is
// tighter than the profile's (unit_spread_words).
std::string verdict_sentence(const CompareResult& result);

// "this unit's range noise is tighter than the profile's: ..." where the spread fails, at least 90 %
// of its failing bins are below the model's, and over all returns the measured spread is below
// 1 / 1.15 of the model's; empty otherwise.
std::string unit_spread_words(const CompareResult& result);

// Every column of the table and of the scores, one array each (names: docs/compare-report.md).
void write_pixels_npz(const std::filesystem::path& path, const PixelTable& table, const PixelScores& scores);

}  // namespace lidartwin
