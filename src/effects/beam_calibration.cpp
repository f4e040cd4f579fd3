// E10 (lidar-physics.md "Per-beam intrinsic calibration errors"): each beam's range has its own
// residual scale and offset after factory calibration, fixed per unit:
//   r_measured = (1 + s_b) * r + dr_b,   dr_b ~ N(0, offset_sigma), s_b ~ N(0, scale_sigma).
// The per-beam values are drawn from unit_seed (one seed = one sensor unit), so the same unit
// keeps its values across frames, captures and the noise seed. Off by default: no published
// per-beam range residuals for Ouster units.
#include <array>
#include <cmath>
#include <cstdint>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

constexpr uint32_t kUnitStream = 0x4531300Au;  // "E10\n": the unit's draws, apart from every noise stream

struct BeamCalibrationParameters {
  double offset_sigma_m = 0.0;
  double scale_sigma = 0.0;
  double unit_seed = 0.0;
};

class BeamCalibration final : public TabledEffect<BeamCalibration, BeamCalibrationParameters> {
 public:
  using P = BeamCalibrationParameters;
  static constexpr std::string_view kName = "beam_calibration";
  static constexpr std::array<ParameterSpec<P>, 3> kSpecs{{
      {"offset_sigma_m", &P::offset_sigma_m, {0.0, 0.5}},
      {"scale_sigma", &P::scale_sigma, {0.0, 0.01}},
      {"unit_seed", &P::unit_seed, {0.0, 4294967295.0}},
  }};
  // The unit's values are drawn once, not per pixel (two Box-Muller draws cost more than the rest
  // of the effect: pipeline_bench's every-effect chain).
  explicit BeamCalibration(const P& p) : TabledEffect(p) {
    for (uint32_t b = 0; b < kTabled; ++b) table_[b] = draw(b);
  }

  // The unit's offset and scale of one beam.
  struct Beam {
    double offset_m = 0.0;
    double scale = 0.0;
  };
  Beam beam(uint32_t b) const { return b < kTabled ? table_[b] : draw(b); }

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext&, MeasuredColumn& measured) const override {
    float* range = measured.range_m.data();
    for (size_t i = 0; i < ideal.size(); ++i) {
      if (range[i] == 0.0f) continue;
      const Beam b = beam(ideal[i].beam);
      range[i] = static_cast<float>((1.0 + b.scale) * static_cast<double>(range[i]) + b.offset_m);
    }
  }

  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    const Beam b = beam(ideal.beam);
    const double mean = static_cast<double>(ideal.range_m) + prediction.bias_m;
    prediction.bias_m += b.scale * mean + b.offset_m;
    prediction.variance_m2 *= (1.0 + b.scale) * (1.0 + b.scale);
  }

 private:
  static constexpr uint32_t kTabled = 128;  // beams of the largest Ouster sensor
  Beam draw(uint32_t b) const {
    const RandomStream unit(static_cast<uint64_t>(params().unit_seed), PixelKey{0, 0, b}, kUnitStream);
    return {params().offset_sigma_m * unit.normal(0), params().scale_sigma * unit.normal(1)};
  }
  std::array<Beam, kTabled> table_;
};

}  // namespace

std::unique_ptr<Effect> make_beam_calibration(const nlohmann::json& params, std::string_view source) {
  return BeamCalibration::create(params, source);
}

}  // namespace lidartwin::effects_detail
