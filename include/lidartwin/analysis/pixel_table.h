#pragma once
// The measured capture beside the model, pixel by pixel (lidar-physics.md 3.2): every pixel of every
// observed column of every frame, with what was measured, what a perfect sensor would have seen
// there (the same beams cast at the column's own time and pose), the features effects depend on,
// and the chain's predicted distribution. One table feeds the scoring, the bins and the fits, and
// is written out for users' own analysis (DIR/pixels.npz).
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/analysis/pixel_likelihood.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

// Columns of the table, one entry per pixel (structure of arrays).
struct PixelTable {
  // Where the pixel is.
  std::vector<uint32_t> frame;   // index of the frame in the capture (0, 1, …)
  std::vector<uint16_t> beam;    // row
  std::vector<uint16_t> column;  // measurement id
  std::vector<double> time_s;    // column timestamp, seconds on the capture's clock
  // Measured (0 where the channel is absent or there was no return).
  std::vector<float> range_m;
  std::vector<float> signal;
  std::vector<float> reflectivity;
  std::vector<float> near_ir;
  std::vector<float> range2_m;
  // The ideal return and its features.
  std::vector<float> ideal_range_m;          // 0: the beam hits nothing in the scene
  std::vector<float> incidence_deg;          // written with set_incidence, which keeps cos_incidence with it
  std::vector<float> cos_incidence;          // as ideal_of hands it to the effects: a fit reads it millions of times
  std::vector<float> material_reflectivity;  // diffuse, 0..1
  std::vector<float> specular;
  std::vector<uint16_t> material;
  // Pixel distances (chessboard, in the frame's beam x measurement-id grid) to the nearest depth
  // discontinuity and to the nearest retroreflective hit: 0 on one, kFarPixels for more than 5.
  static constexpr uint8_t kFarPixels = 6;
  std::vector<uint8_t> retro;
  std::vector<uint8_t> edge;
  std::vector<float> azimuth_deg;  // encoder angle of the column (protocol doc 7.1)
  // The edge partner across a depth step (IdealReturn::partner_*, E6), as the forward model casts it (CastStage).
  std::vector<float> partner_range_m;
  std::vector<float> partner_reflectance;
  std::vector<float> partner_spacing_rad;
  // The nearest retroreflective hit in the pixel's own column (IdealReturn::retro_*, E8).
  std::vector<uint8_t> retro_rows;
  std::vector<float> retro_range_m;
  // The chain's prediction.
  std::vector<float> predicted_bias_m;
  std::vector<float> predicted_sigma_m;  // of the range before quantization
  std::vector<float> p_detect;
  std::vector<float> outlier_mix;
  std::vector<float> partner_mix;  // E6: weight and offset of the component at the partner's range
  std::vector<float> partner_offset_m;
  std::vector<float> partner_sigma_m;  // 0: predicted_sigma_m
  std::vector<float> tail_mix;         // E2's tails: the share of the pixel's own returns in them
  std::vector<float> tail_sigma_m;     // and their sigma
  std::vector<float> expected_signal;
  std::vector<float> expected_near_ir;
  std::vector<float> window_min_m;
  std::vector<float> window_max_m;
  std::vector<float> step_m;  // width of the measured range bins

  // Where the ideal range comes from. The scene gives it exactly. Without one it comes from the
  // data (docs/compare-report.md, "References without a scene"): static mode's temporal mean of
  // the pixel's own returns, or map mode's surface fitted to the other frames' points. A reference
  // made of the sensor's own returns carries the sensor's own mean bias, so the chain's bias is
  // left out of the prediction, but for the part a map's neighbouring beams do not share
  // (Prediction::unshared_bias_m: per-beam offsets, E10, which a map's surface averages away and a
  // temporal mean does not); its own error enters the spread (reference_scale and
  // reference_variance_m2, per pixel) and map mode, which keeps only returns, does not judge
  // detection (p_detect 1).
  enum class Reference : uint8_t { kScene, kTemporalMean, kMap };
  Reference reference = Reference::kScene;
  // Per pixel, with a data reference: the residual's variance is the chain's times
  // reference_scale plus reference_variance_m2. A temporal mean of n returns includes the return
  // itself: scale 1 - 1/n, which is also the residual's share of the degrees of freedom. A map
  // surface fitted to other frames adds its own error: scale 1, variance the surface's along the beam.
  std::vector<float> reference_scale;
  std::vector<float> reference_variance_m2;

  ColumnContext context;  // what every column's context shares (range step, wire limit, signal gain)
  double start_s = 0.0;   // time_s of the capture's first observed column (effects' drift clock)

  size_t size() const { return beam.size(); }
  // The ideal return and column context pixel i stands for, as the chain's predict saw them.
  IdealReturn ideal_of(size_t i) const;
  ColumnContext context_of(size_t i) const;
  void resize(size_t n);
  // Pixel i: where it is (row r of measurement id m of frame f) and what the scan measured there.
  void set_measured(size_t i, uint32_t f, const Scan& scan, int m, int r);
  // Pixel i: the ideal return it stands for (edge and retro as the return's own flags, which the
  // scene table then turns into distances), and the chain's prediction for it.
  void set_ideal(size_t i, const IdealReturn& ideal);
  void set_prediction(size_t i, const Prediction& prediction, const RangeModel& model);
  void set_incidence(size_t i, float degrees);
  // Pixel i's predicted distribution of the measured range under a chain's prediction for it,
  // with the reference's rules applied (see Reference). Every prediction the analysis scores goes
  // through here, the table's own and every refit's.
  RangeModel model_for(size_t i, Prediction prediction) const;
  // What model_for reads of a pixel besides the prediction: the fits gather it once per fitted row.
  struct ModelInputs {
    float ideal_range_m = 0.0f;
    float step_m = 0.0f;
    float window_max_m = 0.0f;
    float reference_scale = 1.0f;        // read only when the reference is not the scene
    float reference_variance_m2 = 0.0f;  // likewise
  };
  ModelInputs model_inputs_of(size_t i) const;
  RangeModel model_for(const ModelInputs& pixel, Prediction prediction) const;
  // The part of a prediction's bias that the reference does not carry (see Reference).
  double bias_against_reference(const Prediction& prediction) const;
  // Predicts pixel i with the chain and stores it (model_for's model).
  void predict(size_t i, const EffectChain& chain);
  // The residual's share of the degrees of freedom (1 but for temporal means: 1 - 1/n).
  double dof_share(size_t i) const {
    return reference == Reference::kTemporalMean ? static_cast<double>(reference_scale[i]) : 1.0;
  }
};

struct PixelTableSetup {
  const MeasuredCapture& capture;
  const Scene& scene;
  const PoseSource& poses;     // world_from_sensor on the capture's clock, shifted by time_offset_s
  double time_offset_s = 0.0;  // pose time = column timestamp + offset
  const EffectChain& chain;    // the profile's: only its effects are used, never its beams or modes
  double max_range_m = 100.0;  // the cast looks 1 m beyond it, as the forward model does
  // Called with the fraction of columns done, at most 100 times, one call at a time (any thread).
  std::function<void(double fraction)> progress = nullptr;
};

// Casts the capture's own beams (metadata) at each column's timestamp and pose. Columns whose
// status is not valid or whose packet never arrived are left out. Throws InputError when a column
// time lies outside the pose source's span, or when the chain predicts no spread for returns.
PixelTable build_pixel_table(const PixelTableSetup& setup, WorkerPool& pool);

// The same table with every pixel's prediction redone by another chain; what was measured, the
// ideal returns and the features are unchanged. (Not for static tables: their predictions are
// adjusted for the temporal mean.)
// pool: the workers that predict (none: the calling thread); the table is the same either way.
PixelTable repredicted(const PixelTable& table, const EffectChain& chain, WorkerPool* pool = nullptr);
// The same into `out`, a copy of `table` (repredicted before or not): only the predictions are
// written, so one table serves a sequence of chains without a copy of the capture each.
void repredict(const PixelTable& table, const EffectChain& chain, PixelTable& out, WorkerPool* pool = nullptr);

// Calls chunk(first, last) for consecutive runs of at most kPixelChunk of [0, n), on the pool's
// workers where it has more than one. The runs are fixed by n alone, so work that writes its own
// pixels, or sums per run and adds the runs in order, comes out the same whatever the pool.
inline constexpr size_t kPixelChunk = 4096;
void for_each_pixel_chunk(size_t n, WorkerPool* pool, const std::function<void(size_t first, size_t last)>& chunk);

}  // namespace lidartwin
