// The capture beside the model: cast the capture's beams at each column's time and pose, run the
// chain's predict, keep what was measured.
#include "lidartwin/analysis/pixel_table.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <functional>
#include <mutex>
#include <numbers>

#include <fmt/format.h>

#include "analysis/capture_points.h"
#include "lidartwin/analysis/pixel_likelihood.h"
#include "lidartwin/caster/column_caster.h"
#include "lidartwin/error.h"
#include "lidartwin/frame/cast_stage.h"
#include "lidartwin/frame/wire_context.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin {
namespace {

struct ObservedColumn {
  uint32_t frame = 0;
  int column = 0;
  size_t first_pixel = 0;
};

float channel_value(const Scan& scan, ChannelField field, int m, int r, float scale) {
  return scan.has(field) ? static_cast<float>(scan.at(field, m, r)) * scale : 0.0f;
}

// Multi-source breadth-first chessboard distance over a W x H grid (columns wrap around: a frame is
// a full turn), capped at PixelTable::kFarPixels. index[m * H + r] is the table row of the pixel,
// or -1 where the column was not observed; seed says where the distance is 0.
void chessboard_distance(const std::vector<int64_t>& index, int width, int height,
                         const std::function<bool(size_t)>& seed, std::vector<uint8_t>& out) {
  std::vector<size_t> frontier, next;
  for (size_t cell = 0; cell < index.size(); ++cell) {
    if (index[cell] < 0) continue;
    const auto row = static_cast<size_t>(index[cell]);
    out[row] = PixelTable::kFarPixels;
    if (seed(row)) {
      out[row] = 0;
      frontier.push_back(cell);
    }
  }
  for (uint8_t d = 1; d < PixelTable::kFarPixels && !frontier.empty(); ++d) {
    next.clear();
    for (const size_t cell : frontier) {
      const int m = static_cast<int>(cell) / height, r = static_cast<int>(cell) % height;
      for (int dm = -1; dm <= 1; ++dm) {
        for (int dr = -1; dr <= 1; ++dr) {
          const int rr = r + dr;
          if (rr < 0 || rr >= height) continue;
          const int mm = (m + dm + width) % width;
          const auto neighbour = static_cast<size_t>(mm * height + rr);
          if (index[neighbour] < 0) continue;
          uint8_t& distance = out[static_cast<size_t>(index[neighbour])];
          if (distance > d) {
            distance = d;
            next.push_back(neighbour);
          }
        }
      }
    }
    frontier.swap(next);
  }
}

// Frame f's pixels in its measurement-id x beam grid: index[m * height + r] = the pixel's row in
// the table, -1 where the column was not observed. observed[first] is the frame's first column;
// returns one past its last.
size_t index_frame(const std::vector<ObservedColumn>& observed, size_t f, size_t first, int height,
                   std::vector<int64_t>& index) {
  std::fill(index.begin(), index.end(), -1);
  size_t last = first;
  while (last < observed.size() && observed[last].frame == f) {
    const ObservedColumn& oc = observed[last++];
    for (int r = 0; r < height; ++r) {
      index[static_cast<size_t>(oc.column * height + r)] = static_cast<int64_t>(oc.first_pixel) + r;
    }
  }
  return last;
}

// Edge and retro distances, frame by frame, once every pixel's ideal return is in the table. On
// entry t.edge holds the caster's vertical-edge flag and t.retro the pixel's own retro flag.
void mark_neighbourhoods(PixelTable& t, const std::vector<ObservedColumn>& observed, size_t frames, int width,
                         int height) {
  std::vector<int64_t> index(static_cast<size_t>(width * height));
  std::vector<uint8_t> edge_seed(t.size(), 0), retro_seed(t.retro);
  size_t first = 0;
  for (size_t f = 0; f < frames; ++f) {
    const size_t last = index_frame(observed, f, first, height, index);
    // Depth steps: the caster's vertical edges, and horizontal ones between neighbouring columns.
    for (size_t i = first; i < last; ++i) {
      const ObservedColumn& oc = observed[i];
      const int right = (oc.column + 1) % width;
      for (int r = 0; r < height; ++r) {
        const auto p = oc.first_pixel + static_cast<size_t>(r);
        if (t.edge[p]) edge_seed[p] = 1;
        const int64_t q = index[static_cast<size_t>(right * height + r)];
        if (q >= 0 && depth_step(t.ideal_range_m[p], t.ideal_range_m[static_cast<size_t>(q)])) {
          edge_seed[p] = edge_seed[static_cast<size_t>(q)] = 1;
        }
      }
    }
    chessboard_distance(
        index, width, height, [&](size_t p) { return edge_seed[p] != 0; }, t.edge);
    chessboard_distance(
        index, width, height, [&](size_t p) { return retro_seed[p] != 0; }, t.retro);
    first = last;
  }
}

}  // namespace

void PixelTable::resize(size_t n) {
  for (auto* v : {&frame}) v->resize(n);
  for (auto* v : {&beam, &column, &material}) v->resize(n);
  time_s.resize(n);
  for (auto* v : {&range_m,
                  &signal,
                  &reflectivity,
                  &near_ir,
                  &range2_m,
                  &ideal_range_m,
                  &incidence_deg,
                  &cos_incidence,
                  &material_reflectivity,
                  &specular,
                  &azimuth_deg,
                  &partner_range_m,
                  &partner_reflectance,
                  &partner_spacing_rad,
                  &retro_range_m,
                  &predicted_bias_m,
                  &predicted_sigma_m,
                  &p_detect,
                  &outlier_mix,
                  &partner_mix,
                  &partner_offset_m,
                  &partner_sigma_m,
                  &tail_mix,
                  &tail_sigma_m,
                  &expected_signal,
                  &expected_near_ir,
                  &window_min_m,
                  &window_max_m,
                  &step_m,
                  &reference_scale,
                  &reference_variance_m2}) {
    v->resize(n);
  }
  for (auto* v : {&retro, &edge, &retro_rows}) v->resize(n);
}

void PixelTable::set_measured(size_t i, uint32_t f, const Scan& scan, int m, int r) {
  frame[i] = f;
  beam[i] = static_cast<uint16_t>(r);
  column[i] = static_cast<uint16_t>(m);
  time_s[i] = static_cast<double>(scan.timestamp_ns[static_cast<size_t>(m)]) * 1e-9;
  range_m[i] = channel_value(scan, ChannelField::kRange, m, r, 0.001f);
  signal[i] = channel_value(scan, ChannelField::kSignal, m, r, 1.0f);
  reflectivity[i] = channel_value(scan, ChannelField::kReflectivity, m, r, 1.0f);
  near_ir[i] = channel_value(scan, ChannelField::kNearIr, m, r, 1.0f);
  range2_m[i] = channel_value(scan, ChannelField::kRange2, m, r, 0.001f);
  azimuth_deg[i] = static_cast<float>(360.0 - 360.0 * m / scan.width);  // encoder angle (7.1)
}

void PixelTable::set_ideal(size_t i, const IdealReturn& ideal) {
  ideal_range_m[i] = ideal.range_m;
  set_incidence(i, ideal.hit()
                       ? static_cast<float>(std::acos(std::clamp(static_cast<double>(ideal.cos_incidence), 0.0, 1.0)) *
                                            180.0 / std::numbers::pi)
                       : 0.0f);
  material_reflectivity[i] = ideal.reflectivity;
  specular[i] = ideal.specular;
  material[i] = static_cast<uint16_t>(ideal.hit() ? ideal.material_id : 0xFFFF);
  retro[i] = ideal.retroreflective;
  edge[i] = ideal.edge;
  partner_range_m[i] = ideal.partner_range_m;
  partner_reflectance[i] = ideal.partner_reflectance;
  partner_spacing_rad[i] = ideal.partner_spacing_rad;
  retro_rows[i] = ideal.retro_rows;
  retro_range_m[i] = ideal.retro_range_m;
}

void PixelTable::set_prediction(size_t i, const Prediction& prediction, const RangeModel& model) {
  // Off a surface the model's mean is its only component's (a halo's, range_model): kept so that
  // the model rebuilt from the table (misfit_features.cpp) is the one scored.
  // A data reference carries (some of) the sensor's own bias: model_for's rule.
  const double bias = bias_against_reference(prediction);
  predicted_bias_m[i] = static_cast<float>(ideal_range_m[i] > 0.0f ? bias : model.mean_m);
  predicted_sigma_m[i] = static_cast<float>(model.sigma_m);
  p_detect[i] = static_cast<float>(model.p_detect);
  outlier_mix[i] = static_cast<float>(model.outlier_mix);
  partner_mix[i] = static_cast<float>(model.partner_mix);
  partner_offset_m[i] = static_cast<float>(model.partner_offset_m);
  partner_sigma_m[i] = static_cast<float>(model.partner_sigma_m);
  tail_mix[i] = static_cast<float>(model.tail_mix);
  tail_sigma_m[i] = static_cast<float>(model.tail_sigma_m);
  expected_signal[i] = static_cast<float>(prediction.signal_photons);
  expected_near_ir[i] = static_cast<float>(prediction.near_ir_photons);
  window_min_m[i] = static_cast<float>(model.window_min_m);
  window_max_m[i] = static_cast<float>(model.window_max_m);
  step_m[i] = static_cast<float>(model.step_m);
}

double PixelTable::bias_against_reference(const Prediction& prediction) const {
  switch (reference) {
    case Reference::kScene: return prediction.bias_m;
    case Reference::kTemporalMean: return 0.0;                // the pixel's own mean: every bias it has
    case Reference::kMap: return prediction.unshared_bias_m;  // neighbouring beams' surface: all they share
  }
  return prediction.bias_m;
}

void PixelTable::set_incidence(size_t i, float degrees) {
  incidence_deg[i] = degrees;
  // The cosine of the angle as stored (not the caster's own): effects see the same value whether
  // the table was just cast or read back.
  cos_incidence[i] = static_cast<float>(std::cos(static_cast<double>(degrees) * std::numbers::pi / 180.0));
}

IdealReturn PixelTable::ideal_of(size_t i) const {
  IdealReturn ideal;
  ideal.range_m = ideal_range_m[i];
  ideal.cos_incidence = cos_incidence[i];
  ideal.reflectivity = material_reflectivity[i];
  ideal.specular = specular[i];
  ideal.material_id = material[i] == 0xFFFF ? 0 : material[i];
  ideal.retroreflective = ideal.hit() && retro[i] == 0 ? 1 : 0;
  ideal.edge = ideal.hit() && edge[i] == 0 ? 1 : 0;
  ideal.beam = beam[i];
  ideal.partner_range_m = partner_range_m[i];
  ideal.partner_reflectance = partner_reflectance[i];
  ideal.partner_spacing_rad = partner_spacing_rad[i];
  ideal.retro_rows = retro_rows[i];
  ideal.retro_range_m = retro_range_m[i];
  return ideal;
}

ColumnContext PixelTable::context_of(size_t i) const {
  ColumnContext c = context;
  c.frame = frame[i];
  c.column = column[i];
  c.time_s = time_s[i] - start_s;
  return c;
}

PixelTable::ModelInputs PixelTable::model_inputs_of(size_t i) const {
  ModelInputs in{ideal_range_m[i], step_m[i], window_max_m[i]};
  if (reference != Reference::kScene) {
    in.reference_scale = reference_scale[i];
    in.reference_variance_m2 = reference_variance_m2[i];
  }
  return in;
}

RangeModel PixelTable::model_for(size_t i, Prediction prediction) const {
  return model_for(model_inputs_of(i), prediction);
}

RangeModel PixelTable::model_for(const ModelInputs& pixel, Prediction prediction) const {
  if (reference != Reference::kScene) {
    prediction.bias_m = bias_against_reference(prediction);
    if (reference == Reference::kMap) prediction.p_detect = 1.0;  // only returns are in a map table
  }
  RangeModel model = range_model(prediction, static_cast<double>(pixel.ideal_range_m),
                                 static_cast<double>(pixel.step_m), static_cast<double>(pixel.window_max_m));
  if (reference != Reference::kScene && model.sigma_m > 0.0) {
    const double scale = static_cast<double>(pixel.reference_scale);
    const double add = static_cast<double>(pixel.reference_variance_m2);
    const auto adjusted = [&](double sigma) { return std::sqrt(sigma * sigma * scale + add); };
    if (model.partner_sigma_m > 0.0) model.partner_sigma_m = adjusted(model.partner_sigma_m);
    if (model.tail_sigma_m > 0.0) model.tail_sigma_m = adjusted(model.tail_sigma_m);
    model.sigma_m = adjusted(model.sigma_m);
  }
  return model;
}

void PixelTable::predict(size_t i, const EffectChain& chain) {
  const Prediction p = chain.predict(ideal_of(i), context_of(i));
  set_prediction(i, p, model_for(i, p));
}

PixelTable repredicted(const PixelTable& t, const EffectChain& chain, WorkerPool* pool) {
  PixelTable out = t;
  repredict(t, chain, out, pool);
  return out;
}

void repredict(const PixelTable& t, const EffectChain& chain, PixelTable& out, WorkerPool* pool) {
  assert(out.size() == t.size());
  for_each_pixel_chunk(t.size(), pool, [&](size_t first, size_t last) {
    for (size_t i = first; i < last; ++i) {
      // The prediction's inputs among the prediction's columns (model_for: the bins' width and the
      // cast's reach), as the source table has them, not as an earlier chain left them.
      out.step_m[i] = t.step_m[i];
      out.window_max_m[i] = t.window_max_m[i];
      out.predict(i, chain);
    }
  });
}

void for_each_pixel_chunk(size_t n, WorkerPool* pool, const std::function<void(size_t first, size_t last)>& chunk) {
  const size_t chunks = (n + kPixelChunk - 1) / kPixelChunk;
  const auto run = [&](size_t c) { chunk(c * kPixelChunk, std::min(n, (c + 1) * kPixelChunk)); };
  if (pool && pool->size() > 1 && chunks > 1) {
    pool->run(static_cast<int>(chunks), [&](int, int c) { run(static_cast<size_t>(c)); });
  } else {
    for (size_t c = 0; c < chunks; ++c) run(c);
  }
}

namespace {

// The columns the table holds: valid ones (their packet arrived, their status says so), in capture
// order, each with where its pixels go. Every column's pose time is checked before any cast.
std::vector<ObservedColumn> observed_columns(const PixelTableSetup& setup) {
  const LidarDataFormat& format = setup.capture.metadata.format;
  const PoseSpan span = setup.poses.span();
  std::vector<ObservedColumn> observed;
  for (size_t f = 0; f < setup.capture.frames.size(); ++f) {
    const Scan& scan = setup.capture.frames[f].scan;
    for (int m = 0; m < format.columns_per_frame; ++m) {
      if (!analysis_detail::column_valid(scan, m, format)) continue;
      const double t = static_cast<double>(scan.timestamp_ns[static_cast<size_t>(m)]) * 1e-9 + setup.time_offset_s;
      if (!span.contains(t)) {
        throw InputError(fmt::format(
            "--pose: frame {} column {} was measured at {:.6f} s (capture clock{}), outside the poses' span "
            "[{:.6f}, {:.6f}] s; shift the poses with --time-offset or give a trajectory that covers the capture",
            f, m, t - setup.time_offset_s,
            setup.time_offset_s != 0.0 ? fmt::format(", {:+.6f} s offset", setup.time_offset_s) : "", span.begin_s,
            span.end_s));
      }
      observed.push_back(
          {static_cast<uint32_t>(f), m, observed.size() * static_cast<size_t>(format.pixels_per_column)});
    }
  }
  return observed;
}

// Effects that drift (E12) count time from the capture's first observed column: a capture does not
// say when the sensor was powered on. Skipped frames count: held-out frames keep their time.
uint64_t first_column_stamp(const MeasuredCapture& capture, const std::vector<ObservedColumn>& observed) {
  uint64_t first = capture.start_ns;
  for (const ObservedColumn& oc : observed) {
    const uint64_t stamp = capture.frames[oc.frame].scan.timestamp_ns[static_cast<size_t>(oc.column)];
    if (first == 0 || stamp < first) first = stamp;
  }
  return first;
}

// Calls progress(fraction) as items finish, at most once per percent, one call at a time.
class ItemProgress {
 public:
  ItemProgress(const std::function<void(double)>& progress, int items) : progress_(progress), items_(items) {}
  void item_done() {
    if (!progress_) return;
    const int percent = static_cast<int>(100LL * ++done_ / std::max(items_, 1));
    int shown = shown_.load();
    while (percent > shown && !shown_.compare_exchange_weak(shown, percent)) {
    }
    if (percent > shown) {
      const std::lock_guard lock(mutex_);
      progress_(percent / 100.0);
    }
  }

 private:
  const std::function<void(double)>& progress_;
  const int items_;
  std::atomic<int> done_{0};
  std::atomic<int> shown_{0};
  std::mutex mutex_;
};

// Each observed column's beams cast from the column's pose at its own timestamp, and each pixel's
// measurement, ideal return and prediction written to the table. The capture's frames go through
// the forward model's cast stage as `record` casts them, a walk along consecutive packets per work
// item: frame f's valid columns are its observed ones, each posed at its own timestamp, its time
// (E12) counted from the capture's first observed column. Returns whether the chain predicted no
// spread for a pixel it detects.
bool cast_and_predict(const PixelTableSetup& setup, const std::vector<ObservedColumn>& observed, const CastStage& cast,
                      uint64_t first_stamp, PixelTable& table, WorkerPool& pool) {
  const LidarDataFormat& format = setup.capture.metadata.format;
  const int width = format.columns_per_frame, height = format.pixels_per_column;
  const int per_packet = format.columns_per_packet;
  const int packets = width / per_packet;
  // first_row[f * width + m]: the table row of frame f's column m's first pixel, -1: not observed.
  std::vector<int64_t> first_row(setup.capture.frames.size() * static_cast<size_t>(width), -1);
  for (const ObservedColumn& oc : observed) {
    first_row[oc.frame * static_cast<size_t>(width) + static_cast<size_t>(oc.column)] =
        static_cast<int64_t>(oc.first_pixel);
  }
  struct Scratch {
    FrameColumns columns;  // the frame's columns; a worker fills those of its piece
    CastStage::Walk walk;
  };
  std::vector<Scratch> scratch;
  for (int w = 0; w < pool.size(); ++w) {
    scratch.push_back({FrameColumns{0, std::vector<Pose>(static_cast<size_t>(width)),
                                    std::vector<uint8_t>(static_cast<size_t>(width)),
                                    std::vector<double>(static_cast<size_t>(width))},
                       cast.make_walk(static_cast<size_t>(per_packet))});
  }
  // Each frame's packets in pieces of consecutive packets, as `record` renders them.
  const std::vector<WorkPiece> pieces = guided_pieces(packets, pool.size());
  const int items = static_cast<int>(setup.capture.frames.size() * pieces.size());
  std::atomic<bool> no_spread{false};
  ItemProgress progress(setup.progress, items);
  pool.run(items, [&](int worker, int item) {
    Scratch& s = scratch[static_cast<size_t>(worker)];
    const auto f = static_cast<size_t>(item) / pieces.size();
    const WorkPiece piece = pieces[static_cast<size_t>(item) % pieces.size()];
    const Scan& scan = setup.capture.frames[f].scan;
    const int64_t* rows = &first_row[f * static_cast<size_t>(width)];
    s.columns.frame_index = f;
    // Column m observed when its packet arrived valid, posed at its own timestamp.
    const ColumnLocator locate = [&](int m) -> std::optional<LocatedColumn> {
      if (rows[m] < 0) return std::nullopt;
      const uint64_t stamp = scan.timestamp_ns[static_cast<size_t>(m)];
      return LocatedColumn{setup.poses.at(static_cast<double>(stamp) * 1e-9 + setup.time_offset_s),
                           static_cast<double>(stamp - first_stamp) * 1e-9};
    };
    const auto prepare = [&](int begin) {
      for (int m = begin; m < begin + per_packet; ++m) {
        const auto column = static_cast<size_t>(m);
        const std::optional<LocatedColumn> located = locate(m);
        s.columns.observed[column] = located ? 1 : 0;
        if (!located) continue;
        s.columns.poses[column] = located->pose;
        s.columns.times_s[column] = located->time_s;
      }
    };
    const auto predict = [&](const CastStage::Block& block) {
      for (int m = block.begin(); m < block.begin() + per_packet; ++m) {
        if (!s.columns.observed[static_cast<size_t>(m)]) continue;
        const ColumnContext context = cast.context(s.columns, m);
        const std::span<const IdealReturn> ideal = block.column(m);
        for (int r = 0; r < height; ++r) {
          const size_t p = static_cast<size_t>(rows[m]) + static_cast<size_t>(r);
          table.set_measured(p, static_cast<uint32_t>(f), scan, m, r);
          IdealReturn hit = ideal[static_cast<size_t>(r)];
          table.set_ideal(p, hit);
          // Predicted at the incidence the table holds (in degrees, PixelTable::set_incidence), so
          // that a fit predicting the pixel again from the table starts from the same figures.
          hit.cos_incidence = table.cos_incidence[p];
          const Prediction prediction = setup.chain.predict(hit, context);
          const RangeModel model = range_model(prediction, hit.range_m, table.context.range_step_m, cast.reach_m());
          if (hit.hit() && model.p_detect > 0.0 && model.sigma_m <= 0.0) no_spread = true;
          table.set_prediction(p, prediction, model);
        }
      }
    };
    cast.walk(s.columns, piece.first * per_packet, piece.size, per_packet, locate, s.walk, prepare, predict);
    progress.item_done();
  });
  return no_spread;
}

}  // namespace

// The phases: which columns, cast (with edge partners) and predict each pixel, the neighbourhood
// features (distances to edges and retroreflectors).
PixelTable build_pixel_table(const PixelTableSetup& setup, WorkerPool& pool) {
  const Metadata& metadata = setup.capture.metadata;
  const LidarDataFormat& format = metadata.format;
  const PacketFormat packets(format);

  const std::vector<ObservedColumn> observed = observed_columns(setup);
  PixelTable table;
  table.resize(observed.size() * static_cast<size_t>(format.pixels_per_column));
  table.context = wire_context(packets, analysis_detail::signal_gain_of(metadata));
  const uint64_t first_stamp = first_column_stamp(setup.capture, observed);
  table.start_s = observed.empty() ? 0.0 : static_cast<double>(first_stamp) * 1e-9;
  const CastStage cast(setup.scene, metadata.beams, format.columns_per_frame, cast_reach_m(setup.max_range_m, packets),
                       setup.chain, table.context, CastStage::Use::kPredict);
  if (cast_and_predict(setup, observed, cast, first_stamp, table, pool)) {
    throw InputError(
        "--profile: its effect chain predicts no range spread (variance 0) for pixels it detects, so no measured "
        "range can be scored against it; compare needs a profile with a range noise effect (e.g. "
        "range_noise_linear or range_noise_piecewise)");
  }
  mark_neighbourhoods(table, observed, setup.capture.frames.size(), format.columns_per_frame, format.pixels_per_column);
  return table;
}

}  // namespace lidartwin
