// E10 (lidar-physics.md "Per-beam intrinsic calibration errors"): each beam's range has its own
// residual scale and offset after factory calibration, fixed per unit:
//   r_measured = (1 + s_b) * r + dr_b.
// Two ways to give them. A unit: dr_b ~ N(0, offset_sigma_m), s_b ~ N(0, scale_sigma), drawn from
// unit_seed (one seed = one sensor unit), so the same unit keeps its values across frames,
// captures and the noise seed. Or tables, as a fit finds them or a user measures them:
// offsets_m[b] and scales[b] (beams beyond a table: 0). Off by default: no published per-beam
// range residuals for Ouster units.
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

constexpr uint32_t kUnitStream = 0x4531300Au;  // "E10\n": the unit's draws, apart from every noise stream
constexpr std::string_view kName = "beam_calibration";
constexpr uint32_t kTabled = 128;  // beams of the largest Ouster sensor
constexpr Bounds kOffsetSigma{0.0, 0.5}, kScaleSigma{0.0, 0.01}, kSeed{0.0, 4294967295.0};
constexpr Bounds kOffset{-0.5, 0.5}, kScale{-0.01, 0.01};

struct Unit {
  double offset_sigma_m = 0.0;
  double scale_sigma = 0.0;
  double unit_seed = 0.0;
};
struct Tables {
  std::vector<double> offsets_m;
  std::vector<double> scales;  // as long as offsets_m
};

// The unit's offset and scale of one beam.
struct Beam {
  double offset_m = 0.0;
  double scale = 0.0;
};

Beam draw(const Unit& u, uint32_t b) {
  const RandomStream unit(static_cast<uint64_t>(u.unit_seed), PixelKey{0, 0, b}, kUnitStream);
  return {u.offset_sigma_m * unit.normal(0), u.scale_sigma * unit.normal(1)};
}

class BeamCalibration final : public Effect {
 public:
  explicit BeamCalibration(const Unit& u) : unit_(u) {
    for (uint32_t b = 0; b < kTabled; ++b) beams_[b] = draw(u, b);
  }
  explicit BeamCalibration(Tables t) : tables_(std::move(t)) {
    for (uint32_t b = 0; b < kTabled && b < tables_->offsets_m.size(); ++b) {
      beams_[b] = {tables_->offsets_m[b], tables_->scales[b]};
    }
  }

  std::string_view name() const override { return kName; }

  // The unit's values are drawn (or read) once, not per pixel (two Box-Muller draws cost more than
  // the rest of the effect: pipeline_bench's every-effect chain).
  Beam beam(uint32_t b) const {
    if (b < kTabled) return beams_[b];
    return tables_ ? Beam{} : draw(unit_, b);
  }

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
    const double bias = b.scale * mean + b.offset_m;
    prediction.bias_m += bias;
    prediction.unshared_bias_m += bias;  // the beam's own: its neighbours do not share it
    prediction.variance_m2 *= (1.0 + b.scale) * (1.0 + b.scale);
  }

  std::vector<EffectParameter> parameters() const override {
    if (!tables_) {
      return {{"offset_sigma_m", unit_.offset_sigma_m, kOffsetSigma.lower, kOffsetSigma.upper},
              {"scale_sigma", unit_.scale_sigma, kScaleSigma.lower, kScaleSigma.upper},
              {"unit_seed", unit_.unit_seed, kSeed.lower, kSeed.upper}};
    }
    std::vector<EffectParameter> out;
    for (size_t b = 0; b < tables_->offsets_m.size(); ++b) {
      out.push_back({"offsets_m/" + std::to_string(b), tables_->offsets_m[b], kOffset.lower, kOffset.upper});
    }
    for (size_t b = 0; b < tables_->scales.size(); ++b) {
      out.push_back({"scales/" + std::to_string(b), tables_->scales[b], kScale.lower, kScale.upper});
    }
    return out;
  }

  std::unique_ptr<Effect> with_parameters(std::span<const double> values) const override {
    std::unique_ptr<Effect> copy;
    if (!tables_) {
      check_count(values.size(), 3, kName);
      check_number(values[0], fitted(kName).child("offset_sigma_m"), kOffsetSigma);
      check_number(values[1], fitted(kName).child("scale_sigma"), kScaleSigma);
      check_number(values[2], fitted(kName).child("unit_seed"), kSeed);
      copy = std::make_unique<BeamCalibration>(Unit{values[0], values[1], values[2]});
    } else {
      const size_t n = tables_->offsets_m.size();
      check_count(values.size(), 2 * n, kName);
      Tables t{std::vector<double>(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(n)),
               std::vector<double>(values.begin() + static_cast<std::ptrdiff_t>(n), values.end())};
      for (size_t b = 0; b < n; ++b) {
        check_number(t.offsets_m[b], fitted(kName).child("offsets_m").child(b), kOffset);
        check_number(t.scales[b], fitted(kName).child("scales").child(b), kScale);
      }
      copy = std::make_unique<BeamCalibration>(std::move(t));
    }
    copy->set_stream_id(stream_id());
    return copy;
  }

 private:
  Unit unit_;
  std::optional<Tables> tables_;
  std::array<Beam, kTabled> beams_{};
};

std::vector<double> read_table(const nlohmann::json& params, const Location& at, const char* key, Bounds bounds) {
  const auto found = params.find(key);
  if (found == params.end()) return {};
  const Location where = at.child(key);
  if (!found->is_array()) where.fail_expected("an array of per-beam values", *found);
  if (found->size() > kTabled) where.fail("at most " + std::to_string(kTabled) + " beams");
  std::vector<double> values;
  for (size_t b = 0; b < found->size(); ++b) values.push_back(read_number((*found)[b], where.child(b), bounds));
  return values;
}

}  // namespace

std::unique_ptr<Effect> make_beam_calibration(const nlohmann::json& params, const Location& at) {
  static constexpr std::array<std::string_view, 5> kKeys{"offset_sigma_m", "scale_sigma", "unit_seed", "offsets_m",
                                                         "scales"};
  check_keys(params, at, kName, kKeys);
  const bool tables = params.contains("offsets_m") || params.contains("scales");
  const bool unit = params.contains("offset_sigma_m") || params.contains("scale_sigma") || params.contains("unit_seed");
  if (tables && unit) {
    at.fail(
        "give either a unit (offset_sigma_m, scale_sigma, unit_seed) or per-beam tables (offsets_m, "
        "scales), not both");
  }
  if (tables) {
    Tables t{read_table(params, at, "offsets_m", kOffset), read_table(params, at, "scales", kScale)};
    const size_t n = std::max(t.offsets_m.size(), t.scales.size());
    t.offsets_m.resize(n, 0.0);
    t.scales.resize(n, 0.0);
    return std::make_unique<BeamCalibration>(std::move(t));
  }
  Unit u;
  if (params.contains("offset_sigma_m")) {
    u.offset_sigma_m = read_number(params["offset_sigma_m"], at.child("offset_sigma_m"), kOffsetSigma);
  }
  if (params.contains("scale_sigma")) {
    u.scale_sigma = read_number(params["scale_sigma"], at.child("scale_sigma"), kScaleSigma);
  }
  if (params.contains("unit_seed")) {
    u.unit_seed = read_number(params["unit_seed"], at.child("unit_seed"), kSeed);
  }
  return std::make_unique<BeamCalibration>(u);
}

// Per-beam offsets and scales: fitted in closed form (fit_beam_calibration), not by BOBYQA over 128
// numbers, and only as a missing effect. A pixel's temporal mean carries them.
EffectCard beam_calibration_card() {
  return {.catalogue = "E10", .candidate = true, .refit_in_place = false, .seen_against_temporal_mean = false};
}

}  // namespace lidartwin::effects_detail
