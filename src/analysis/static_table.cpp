// Static mode's pixel table: each pixel's temporal mean stands in for the ideal range.
#include "lidartwin/analysis/static_table.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <fmt/format.h>

#include "analysis/capture_points.h"
#include "lidartwin/analysis/pixel_likelihood.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/wire_context.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin {
namespace {

// Two frames give each pixel a spread about its mean (one degree of freedom, which the misfit's
// tests count: PixelTable::dof_share).
constexpr size_t kMinFrames = 2;

struct Series {
  size_t returns = 0;
  double sum = 0.0, sum2 = 0.0, reflectivity = 0.0;
};

// Each pixel's returns over the frames: count, sum, sum of squares and reflectivity.
std::vector<Series> temporal_series(const MeasuredCapture& capture, bool has_reflectivity) {
  const int width = capture.metadata.format.columns_per_frame;
  const int height = capture.metadata.format.pixels_per_column;
  std::vector<Series> series(static_cast<size_t>(width * height));
  for (const BatchedFrame& frame : capture.frames) {
    const Scan& scan = frame.scan;
    for (int m = 0; m < width; ++m) {
      for (int r = 0; r < height; ++r) {
        const uint32_t mm = scan.at(ChannelField::kRange, m, r);
        if (mm == 0) continue;
        Series& s = series[static_cast<size_t>(m * height + r)];
        const double range = mm * 0.001;
        ++s.returns;
        s.sum += range;
        s.sum2 += range * range;
        if (has_reflectivity) s.reflectivity += scan.at(ChannelField::kReflectivity, m, r);
      }
    }
  }
  return series;
}

// The ideal return a pixel's series stands for: its temporal mean, at the reflectivity it reported.
// Its incidence is unknown without a scene and taken as normal: E4's footprint spread is then not
// predicted (lidartwin's own os1-128 capture of the hall: 2.4 times the spread predicted on dark
// targets, +2,071 standard errors). Estimating it from the neighbours' means took that to +164 but
// scrambled close-range real captures (crc_test at 1-2 m, where two frames' noise is as large as
// the spacing of neighbouring pixels): it needs a plane fitted over a wider window.
IdealReturn ideal_of(const Series& s, bool has_reflectivity, int beam) {
  const auto n = static_cast<double>(s.returns);
  IdealReturn ideal;
  ideal.range_m = static_cast<float>(s.sum / n);
  ideal.cos_incidence = 1.0f;  // unknown without a scene
  // REFLECTIVITY's calibrated byte is percent for Lambertian targets (lidar-physics.md 2.1).
  ideal.reflectivity = has_reflectivity ? static_cast<float>(std::clamp(s.reflectivity / n / 100.0, 0.01, 1.0)) : 0.5f;
  ideal.beam = static_cast<uint16_t>(beam);
  return ideal;
}

// Drift (E12) counts from the capture's first column, as in the scene table.
uint64_t first_column_stamp(const MeasuredCapture& capture) {
  uint64_t first = capture.start_ns != 0 ? capture.start_ns : std::numeric_limits<uint64_t>::max();
  for (const BatchedFrame& frame : capture.frames) {
    for (const uint64_t stamp : frame.scan.timestamp_ns) {
      if (stamp > 0) first = std::min(first, stamp);
    }
  }
  return first;
}

// A moving sensor's frames do not repeat: static mode would score the motion as spread (the real
// OS-1-128 sample, which travels 0.75 m: +4,347 standard errors). Refused when the range of more
// than kMovedShare of the pixels that returned in the first and the last frame changed by more than
// kMovedM between them: far beyond a static sensor's noise, and beyond what people walking
// through its view change.
constexpr double kMovedM = 0.2;
constexpr double kMovedShare = 0.25;
void refuse_a_moving_sensor(const MeasuredCapture& capture) {
  const auto& first = capture.frames.front().scan.channels[static_cast<int>(ChannelField::kRange)];
  const auto& last = capture.frames.back().scan.channels[static_cast<int>(ChannelField::kRange)];
  std::vector<double> change;
  for (size_t i = 0; i < std::min(first.size(), last.size()); ++i) {
    if (first[i] == 0 || last[i] == 0) continue;
    change.push_back(0.001 * std::abs(static_cast<double>(first[i]) - static_cast<double>(last[i])));
  }
  if (change.size() < 100) return;
  const auto moved = static_cast<double>(std::ranges::count_if(change, [](double d) { return d > kMovedM; }));
  const double share = moved / static_cast<double>(change.size());
  if (share <= kMovedShare) return;
  const auto middle = change.begin() + static_cast<std::ptrdiff_t>(change.size() / 2);
  std::nth_element(change.begin(), middle, change.end());
  throw InputError(fmt::format(
      "--static: the sensor moved: between frame 0 and frame {} the range of {:.0f} % of the {} pixels that "
      "returned in both changed by more than {:.0f} cm (median change {:.1f} cm); static mode needs a motionless "
      "sensor's repeated frames: compare with --map (it registers the frames to each other) or with --scene and "
      "--pose",
      capture.frames.size() - 1, 100.0 * share, change.size(), 100.0 * kMovedM, 100.0 * *middle));
}

}  // namespace

// The phases: each pixel's temporal series, the pixels kept (enough returns, away from the range
// limits), then one row per kept pixel and frame, predicted at its temporal mean.
PixelTable build_static_table(const StaticTableSetup& setup) {
  const MeasuredCapture& capture = setup.capture;
  const LidarDataFormat& format = capture.metadata.format;
  const int width = format.columns_per_frame;
  const int height = format.pixels_per_column;
  const size_t frames = capture.frames.size();
  if (frames < kMinFrames) {
    throw InputError(fmt::format("--static: the capture has {} frame{}; a pixel's temporal spread needs at least {}",
                                 frames, frames == 1 ? "" : "s", kMinFrames));
  }
  refuse_a_moving_sensor(capture);
  const PacketFormat packets(format);
  const bool has_reflectivity = packets.has_channel(ChannelField::kReflectivity);
  const std::vector<Series> series = temporal_series(capture, has_reflectivity);
  const auto min_returns = static_cast<size_t>(std::ceil(setup.min_return_fraction * static_cast<double>(frames)));
  // The unit's signal_multiplier scales the SIGNAL it reports, which signal-driven effects (E2, E5)
  // read.
  const ColumnContext context = wire_context(packets, analysis_detail::signal_gain_of(capture.metadata));
  const double reach = cast_reach_m(setup.max_range_m, packets);

  // Pixels within 4 sigma of a range limit are left out: the limit cuts their returns, so the
  // temporal mean of what came back is biased, and so would be everything predicted from it.
  std::vector<uint8_t> keep(series.size(), 0);
  size_t kept = 0, near_limits = 0;
  for (size_t i = 0; i < series.size(); ++i) {
    if (series[i].returns < std::max<size_t>(min_returns, 2)) continue;
    const IdealReturn ideal = ideal_of(series[i], has_reflectivity, static_cast<int>(i % static_cast<size_t>(height)));
    ColumnContext pixel_context = context;  // the column's encoder angle matters to a window sector (E16)
    pixel_context.column = static_cast<uint32_t>(i / static_cast<size_t>(height));
    const RangeModel model =
        range_model(setup.chain.predict(ideal, pixel_context), ideal.range_m, context.range_step_m, reach);
    if (model.sigma_m <= 0.0) {
      throw InputError(
          "--profile: its effect chain predicts no range spread (variance 0), so static mode has "
          "nothing to compare the measured spread with");
    }
    const double margin = 4.0 * model.sigma_m;
    const auto range = static_cast<double>(ideal.range_m);
    if (range - model.window_min_m < margin || model.window_max_m - range < margin) {
      ++near_limits;
      continue;
    }
    keep[i] = 1;
    ++kept;
  }
  if (kept == 0) {
    throw InputError(
        fmt::format("--static: no pixel returned in at least {} of the {} frames away from the profile's "
                    "range limits ({} pixels lie within 4 sigma of them)",
                    min_returns, frames, near_limits));
  }

  PixelTable t;
  t.reference = PixelTable::Reference::kTemporalMean;
  t.resize(kept * frames);
  t.context = context;
  t.start_s = static_cast<double>(first_column_stamp(capture)) * 1e-9;
  size_t p = 0;
  for (size_t f = 0; f < frames; ++f) {
    const Scan& scan = capture.frames[f].scan;
    for (int m = 0; m < width; ++m) {
      for (int r = 0; r < height; ++r) {
        const auto index = static_cast<size_t>(m * height + r);
        if (!keep[index]) continue;
        const Series& s = series[index];
        const auto n = static_cast<double>(s.returns);
        t.set_measured(p, static_cast<uint32_t>(f), scan, m, r);
        t.set_ideal(p, ideal_of(s, has_reflectivity, r));
        t.material[p] = 0xFFFF;  // no scene: no material; incidence, edges and retros unknown (not binned)
        t.edge[p] = t.retro[p] = PixelTable::kFarPixels;
        // Residuals about a mean estimated from the same n returns spread by sqrt(1 - 1/n) less.
        t.reference_scale[p] = static_cast<float>(1.0 - 1.0 / n);
        t.reference_variance_m2[p] = 0.0f;
        t.step_m[p] = context.range_step_m;  // the window and step the prediction is scored with
        t.window_max_m[p] = static_cast<float>(reach);
        t.predict(p, setup.chain);
        ++p;
      }
    }
  }
  return t;
}

}  // namespace lidartwin
