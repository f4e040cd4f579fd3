// report.json and pixels.npz: every number the comparison made, for scripts and for the plots.
#include "lidartwin/analysis/compare_report.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "lidartwin/analysis/npz_writer.h"

namespace lidartwin {
namespace {

nlohmann::json region_json(const Region& region) {
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [name, range] : region) out[name] = {range[0], range[1]};
  return out;
}

nlohmann::json bin_json(const BinMisfit& b) {
  return {{"features", region_json(b.region)},
          {"pixels", b.pixels},
          {"returns", b.returns},
          {"inliers", b.inliers},
          {"detection", {{"measured", b.detection_measured}, {"predicted", b.detection_predicted}}},
          {"bias_m", {{"measured", b.bias_measured_m}, {"predicted", b.bias_predicted_m}}},
          {"spread_m", {{"measured", b.spread_measured_m}, {"predicted", b.spread_predicted_m}}},
          {"spread_ratio", b.spread_ratio},
          {"outliers", {{"measured", b.outliers_measured}, {"predicted", b.outliers_predicted}}},
          {"misfit_nats",
           {{"bias", b.misfit_bias},
            {"spread", b.misfit_spread},
            {"detection", b.misfit_detection},
            {"outliers", b.misfit_outliers}}},
          {"nll", b.nll},
          {"nll_expected", b.nll_expected},
          {"p_value",
           {{"bias", b.p_bias}, {"spread", b.p_spread}, {"detection", b.p_detection}, {"outliers", b.p_outliers}}}};
}

}  // namespace

WaterfallStep waterfall_step(const std::string& profile, const PixelTable& t, const Misfit& misfit,
                             const std::vector<std::string>& material_names) {
  WaterfallStep w;
  w.profile = profile;
  w.failing_runs = failing_runs(misfit, material_names);
  w.nll_per_pixel = misfit.summary.nll_per_pixel;
  w.nll_expected = misfit.summary.nll_expected;
  w.nll_se = misfit.summary.nll_se;
  w.failing = misfit.failing.size();
  double sum2 = 0.0;
  std::vector<double> ratios;
  for (const BinMisfit& b : misfit.bins) {
    if (b.region.size() == 2 && b.region[0].first == "range" && b.region[1].first == "reflectivity") {
      const double excess = b.nll - b.nll_expected;
      (excess < 0.0 ? w.excess_below : w.excess_above) += excess;
    }
  }
  if (misfit.summary.pixels > 0) {
    w.excess_below /= static_cast<double>(misfit.summary.pixels);
    w.excess_above /= static_cast<double>(misfit.summary.pixels);
  }
  for (const BinMisfit& b : misfit.bins) {
    if (b.region.size() != 1 || b.inliers < 30) continue;
    const double d = b.bias_measured_m - b.bias_predicted_m;
    sum2 += d * d;
    ratios.push_back(b.spread_ratio);
  }
  if (!ratios.empty()) {
    w.bias_rms_m = std::sqrt(sum2 / static_cast<double>(ratios.size()));
    std::nth_element(ratios.begin(), ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2), ratios.end());
    w.spread_ratio_median = ratios[ratios.size() / 2];
  }
  double loss = 0.0;
  size_t hits = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    if (t.ideal_range_m[i] <= 0.0f) continue;
    const double p = std::clamp(static_cast<double>(t.p_detect[i]), 1e-6, 1.0 - 1e-6);
    loss -= t.range_m[i] > 0.0f ? std::log(p) : std::log(1.0 - p);
    ++hits;
  }
  w.detection_log_loss = hits > 0 ? loss / static_cast<double>(hits) : 0.0;
  return w;
}

std::vector<ResidualHistogram> residual_histograms(const PixelTable& t, const PixelScores& s) {
  std::vector<ResidualHistogram> bands;
  for (const auto& [lo, hi] : {std::pair{0.0, 5.0}, {5.0, 13.0}, {13.0, 35.0}, {35.0, 1e4}}) {
    bands.push_back({lo, hi, 0, std::vector<uint32_t>(ResidualHistogram::kBins, 0)});
  }
  constexpr double kHalfWidth = 6.0;
  for (size_t i = 0; i < t.size(); ++i) {
    const double ideal = t.ideal_range_m[i];
    if (t.range_m[i] <= 0.0f || ideal <= 0.0 || s.impossible[i]) continue;
    for (ResidualHistogram& band : bands) {
      if (ideal < band.lo_m || ideal >= band.hi_m) continue;
      const double u = (static_cast<double>(s.z[i]) + kHalfWidth) / (2 * kHalfWidth);
      const int k = std::clamp(static_cast<int>(u * ResidualHistogram::kBins), 0, ResidualHistogram::kBins - 1);
      ++band.counts[static_cast<size_t>(k)];
      ++band.returns;
    }
  }
  return bands;
}

RangeImage range_image(const PixelTable& t, const PixelScores& s, const Misfit& misfit) {
  RangeImage image;
  for (const uint16_t beam : t.beam) image.beams = std::max(image.beams, beam + 1);
  const size_t cells = static_cast<size_t>(image.beams) * RangeImage::kAzimuthBins;
  struct Cell {
    double pixels = 0, returns = 0, expected = 0, inliers = 0, z = 0, z2 = 0, outliers = 0;
  };
  std::vector<Cell> acc(cells);
  for (size_t i = 0; i < t.size(); ++i) {
    if (t.ideal_range_m[i] <= 0.0f) continue;
    const double turn = std::fmod(static_cast<double>(t.azimuth_deg[i]) / 360.0 + 1.0, 1.0);
    const int sector = std::min(static_cast<int>(turn * RangeImage::kAzimuthBins), RangeImage::kAzimuthBins - 1);
    Cell& c = acc[static_cast<size_t>(t.beam[i]) * RangeImage::kAzimuthBins + static_cast<size_t>(sector)];
    c.pixels += 1;
    c.expected += static_cast<double>(t.p_detect[i]);
    if (t.range_m[i] <= 0.0f) continue;
    c.returns += 1;
    const double z = s.z[i];
    if (s.impossible[i] || std::abs(z) > 5.0) {  // as the misfit counts outliers
      c.outliers += 1;
      continue;
    }
    c.inliers += 1;
    c.z += z;
    c.z2 += z * z;
  }
  image.pixels.resize(cells);
  for (size_t k = 0; k < cells; ++k) image.pixels[k] = static_cast<uint32_t>(acc[k].pixels);
  const auto fails = [&](const std::string& q) {
    return std::any_of(misfit.failing.begin(), misfit.failing.end(), [&](const auto& f) { return f.quantity == q; });
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto add = [&](const char* quantity, auto value) {
    if (!fails(quantity)) return;
    std::vector<float> values(cells);
    for (size_t k = 0; k < cells; ++k) values[k] = static_cast<float>(value(acc[k]));
    image.quantities.emplace_back(quantity, std::move(values));
  };
  add("bias", [&](const Cell& c) { return c.inliers > 0 ? c.z / c.inliers : nan; });
  add("spread", [&](const Cell& c) {
    if (c.inliers < 2) return nan;
    const double mean = c.z / c.inliers;
    return std::sqrt(std::max(c.z2 / c.inliers - mean * mean, 0.0));
  });
  add("detection", [&](const Cell& c) { return c.pixels > 0 ? (c.returns - c.expected) / c.pixels : nan; });
  add("outliers", [&](const Cell& c) { return c.returns > 0 ? c.outliers / c.returns : nan; });
  return image;
}

namespace {

nlohmann::json image_json(const RangeImage& image) {
  nlohmann::json quantities = nlohmann::json::object();
  for (const auto& [name, values] : image.quantities) {
    nlohmann::json rounded = nlohmann::json::array();
    for (const float v : values) {  // 4 digits are all a picture shows; NaN is written as null
      rounded.push_back(std::isfinite(v) ? nlohmann::json(std::round(static_cast<double>(v) * 1e4) / 1e4)
                                         : nlohmann::json());
    }
    quantities[name] = std::move(rounded);
  }
  return {
      {"beams", image.beams},
      {"azimuth_bins", RangeImage::kAzimuthBins},
      {"layout", "beam-major: index beam * azimuth_bins + sector; sector k covers [k, k + 1) * 360 / azimuth_bins deg"},
      {"pixels", image.pixels},
      {"quantities", quantities}};
}

nlohmann::json runs_json(const std::vector<FailingRun>& runs) {
  nlohmann::json out = nlohmann::json::array();
  for (const FailingRun& run : runs) {
    out.push_back({{"quantity", run.quantity},
                   {"features", region_json(run.region)},
                   {"bins", run.bins},
                   {"pixels", run.pixels},
                   {"misfit_nats", run.misfit_nats},
                   {"localized_nats", run.localized_nats},
                   {"p_value", run.p_value},
                   {"where", run.where},
                   {"everywhere", run.everywhere},
                   {"rides_along", run.rides_along},
                   {"trend", run.trend},
                   {"sentence", run.sentence}});
  }
  return out;
}

}  // namespace

std::string excess_note(const WaterfallStep& before, const WaterfallStep& w) {
  const auto excess = [](const WaterfallStep& x) {
    return x.nll_se > 0 ? (x.nll_per_pixel - x.nll_expected) / x.nll_se : 0.0;
  };
  const double lower = before.nll_per_pixel - w.nll_per_pixel, e0 = excess(before), e1 = excess(w);
  // The excess is the NLL less what the profile itself expects: below it where the profile is too
  // wide, above where too narrow, the two cancelling in the average. A fit that mends where the
  // model was too wide takes away the part that hid what is still too narrow.
  const std::string parts = fmt::format(
      "over range x reflectivity bins, {} is {:+.4f} nats a pixel where its NLL lies below its expectation (too "
      "wide or too unsure there) and {:+.4f} where above (too narrow or too sure); {} {:+.4f} and {:+.4f}",
      before.profile, before.excess_below, before.excess_above, w.profile, w.excess_below, w.excess_above);
  if (lower > 0.0 && std::abs(e1) > std::abs(e0) + 1.0) {
    return fmt::format(
        "{} fits better than {} (NLL {:.4f} a pixel lower) although its excess moved from {:+.1f} to {:+.1f} "
        "standard errors: the excess is the NLL less what each profile expects of itself, and where one region is "
        "too wide and another too narrow the two cancel in the average ({}). Rank profiles by NLL; the failing "
        "regions say where each still errs.",
        w.profile, before.profile, lower, e0, e1, parts);
  }
  if (lower < 0.0 && std::abs(e1) + 1.0 < std::abs(e0)) {
    return fmt::format(
        "{} fits worse than {} (NLL {:.4f} a pixel higher) although its excess is nearer 0 ({:+.1f} against "
        "{:+.1f} standard errors): a wider model expects a higher NLL and can meet it while misfitting ({}). Rank "
        "profiles by NLL; the failing regions say where each errs.",
        w.profile, before.profile, -lower, e1, e0, parts);
  }
  return "";
}

void note_waterfall(std::vector<WaterfallStep>& steps) {
  for (size_t k = 1; k < steps.size(); ++k) steps[k].note = excess_note(steps[k - 1], steps[k]);
}

nlohmann::json waterfall_json(const std::vector<WaterfallStep>& steps) {
  nlohmann::json out = nlohmann::json::array();
  for (const WaterfallStep& w : steps) {
    out.push_back({{"profile", w.profile},
                   {"nll_per_pixel", w.nll_per_pixel},
                   {"nll_expected", w.nll_expected},
                   {"nll_se", w.nll_se},
                   {"bias_rms_m", w.bias_rms_m},
                   {"spread_ratio_median", w.spread_ratio_median},
                   {"detection_log_loss", w.detection_log_loss},
                   {"failing_regions", w.failing},
                   {"failing_runs", runs_json(w.failing_runs)},
                   {"excess_below", w.excess_below},
                   {"excess_above", w.excess_above},
                   {"note", w.note}});
  }
  return out;
}

namespace {

nlohmann::json refinement_json(const PoseRefinement& r) {
  const Eigen::Vector3d t = r.correction.translation;
  const Eigen::Quaterniond q = r.correction.rotation;
  return {{"correction", {{"translation_m", {t.x(), t.y(), t.z()}}, {"rotation_xyzw", {q.x(), q.y(), q.z(), q.w()}}}},
          {"sensor_shift_m", {r.sensor_shift_m.x(), r.sensor_shift_m.y(), r.sensor_shift_m.z()}},
          {"rotation_deg", r.rotation_deg},
          {"rms_before_m", r.rms_before_m},
          {"rms_after_m", r.rms_after_m},
          {"points", r.points},
          {"iterations", r.iterations}};
}

nlohmann::json inputs_json(const CompareInputs& in) {
  nlohmann::json out = {{"capture", in.capture},
                        {"metadata", in.metadata},
                        {"scene", in.scene},
                        {"pose", in.pose},
                        {"static", in.static_mode},
                        {"map", in.map_mode},
                        {"profile", in.profile},
                        {"time_offset_s", in.time_offset_s},
                        {"frames", in.frames},
                        {"skipped_frames", in.skipped_frames},
                        {"lidar_mode", in.lidar_mode},
                        {"udp_profile_lidar", in.udp_profile_lidar},
                        {"seed", in.seed}};
  if (!in.missing_fields.empty()) out["missing_fields"] = in.missing_fields;
  out["columns_not_received"] = in.columns_not_received;
  if (in.pose_refinement) out["pose_refinement"] = refinement_json(*in.pose_refinement);
  if (in.registration) {
    const FrameRegistration& r = *in.registration;
    out["registration"] = {
        {"iterations", r.iterations}, {"pairs", r.pairs}, {"rms_m", r.rms_m}, {"path_length_m", r.path_length_m}};
  }
  if (in.map) {  // in place of map mode's `true`: what it compared and what it left out
    const MapExclusions& x = *in.map;
    out["map"] = {{"returns", x.returns},
                  {"compared", x.compared},
                  {"excluded",
                   {{"edge", x.edge},
                    {"unsupported", x.unsupported},
                    {"not_surface", x.not_surface},
                    {"off_surface", x.off_surface},
                    {"grazing", x.grazing}}},
                  {"within_frame", in.map_within_frame}};
  }
  return out;
}

}  // namespace

nlohmann::json report_json(const CompareResult& result) {
  const Misfit& misfit = result.misfit;
  const double alpha = result.alpha;
  const MisfitSummary& s = misfit.summary;
  nlohmann::json report;
  report["schema"] = kCompareReportSchema;
  if (result.unit_range_spread > 0.0) {
    report["unit_to_unit"] = {{"range_spread", result.unit_range_spread}, {"source", result.unit_to_unit_source}};
  }
  report["verdict_sentence"] = verdict_sentence(result);
  if (!result.next_command.empty()) report["next_command"] = result.next_command;
  report["inputs"] = inputs_json(result.inputs);
  report["summary"] = {{"frames", s.frames},
                       {"pixels", s.pixels},
                       {"returns", s.returns},
                       {"nll_per_pixel", s.nll_per_pixel},
                       {"nll_expected", s.nll_expected},
                       {"nll_se", s.nll_se},
                       {"detection", {{"measured", s.detection_measured}, {"predicted", s.detection_predicted}}},
                       {"unexpected_returns", s.unexpected_returns},
                       {"impossible_misses", s.impossible_misses},
                       {"z", {{"mean", s.z_mean}, {"std", s.z_std}}},
                       {"pit_histogram", s.pit_histogram},
                       {"pit_uniformity_p", s.pit_uniformity_p},
                       {"alpha", alpha},
                       {"tests", s.tests},
                       {"failing_regions", misfit.failing.size()}};
  if (!result.waterfall.empty()) {  // the excess's two parts (WaterfallStep), the report's profile's
    report["summary"]["nll_excess_below"] = result.waterfall.back().excess_below;
    report["summary"]["nll_excess_above"] = result.waterfall.back().excess_above;
  }
  nlohmann::json failing = nlohmann::json::array();
  for (const FailingRegion& f : misfit.failing) {
    failing.push_back({{"quantity", f.quantity},
                       {"features", region_json(f.region)},
                       {"measured", f.measured},
                       {"predicted", f.predicted},
                       {"unit", f.quantity == "bias" || f.quantity == "spread" ? "m" : "fraction"},
                       {"pixels", f.pixels},
                       {"p_value", f.p_value},
                       {"misfit_nats", f.misfit_nats},
                       {"misfit_per_pixel", f.misfit_per_pixel},
                       {"sentence", f.sentence}});
  }
  report["failing"] = std::move(failing);
  report["failing_runs"] = runs_json(failing_runs(misfit, result.inputs.material_names));
  nlohmann::json bins = nlohmann::json::array();
  for (const BinMisfit& b : misfit.bins) bins.push_back(bin_json(b));
  report["bins"] = std::move(bins);
  if (result.waterfall.size() > 1) report["waterfall"] = waterfall_json(result.waterfall);
  if (result.diagnosis) report["diagnosis"] = diagnosis_json(*result.diagnosis);
  if (result.image) report["range_image"] = image_json(*result.image);
  if (!result.residuals.empty()) {
    nlohmann::json residuals = nlohmann::json::array();
    for (const ResidualHistogram& h : result.residuals) {
      residuals.push_back(
          {{"range_m", {h.lo_m, h.hi_m}}, {"returns", h.returns}, {"z", {-6.0, 6.0}}, {"counts", h.counts}});
    }
    report["residual_histograms"] = std::move(residuals);
  }
  return report;
}

void write_pixels_npz(const std::filesystem::path& path, const PixelTable& t, const PixelScores& s) {
  NpzWriter npz(path);
  npz.add("frame", std::span<const uint32_t>(t.frame));
  npz.add("beam", std::span<const uint16_t>(t.beam));
  npz.add("column", std::span<const uint16_t>(t.column));
  npz.add("time_s", std::span<const double>(t.time_s));
  npz.add("range_m", std::span<const float>(t.range_m));
  npz.add("signal", std::span<const float>(t.signal));
  npz.add("reflectivity", std::span<const float>(t.reflectivity));
  npz.add("near_ir", std::span<const float>(t.near_ir));
  npz.add("range2_m", std::span<const float>(t.range2_m));
  npz.add("ideal_range_m", std::span<const float>(t.ideal_range_m));
  npz.add("incidence_deg", std::span<const float>(t.incidence_deg));
  npz.add("material_reflectivity", std::span<const float>(t.material_reflectivity));
  npz.add("material", std::span<const uint16_t>(t.material));
  npz.add("retro", std::span<const uint8_t>(t.retro));
  npz.add("edge", std::span<const uint8_t>(t.edge));
  npz.add("azimuth_deg", std::span<const float>(t.azimuth_deg));
  npz.add("predicted_bias_m", std::span<const float>(t.predicted_bias_m));
  npz.add("predicted_sigma_m", std::span<const float>(t.predicted_sigma_m));
  npz.add("p_detect", std::span<const float>(t.p_detect));
  npz.add("outlier_mix", std::span<const float>(t.outlier_mix));
  npz.add("expected_signal", std::span<const float>(t.expected_signal));
  npz.add("expected_near_ir", std::span<const float>(t.expected_near_ir));
  npz.add("window_min_m", std::span<const float>(t.window_min_m));
  npz.add("window_max_m", std::span<const float>(t.window_max_m));
  npz.add("step_m", std::span<const float>(t.step_m));
  npz.add("reference_variance_m2", std::span<const float>(t.reference_variance_m2));  // map mode: its own error
  npz.add("nll", std::span<const float>(s.nll));
  npz.add("nll_expected", std::span<const float>(s.nll_expected));
  npz.add("z", std::span<const float>(s.z));
  npz.add("predicted_mean_m", std::span<const float>(s.mean_m));
  npz.add("predicted_sd_m", std::span<const float>(s.sd_m));
  npz.add("pit", std::span<const float>(s.pit));
  npz.add("impossible", std::span<const uint8_t>(s.impossible));
  npz.close();
}

}  // namespace lidartwin
