// E11 (lidar-physics.md "Motion distortion, vibration"): the mount shakes the sensor, so each
// column is fired from a pose a little off the trajectory's. All beams of a column fire at once:
// one jitter per column, a function of the column's time. The jitter about each of the sensor's
// three axes, and along each, is band-limited noise: a sum of kTones sinusoids at frequencies
// drawn uniformly in [band_low_hz, band_high_hz] with random phases (fixed by unit_seed, like a
// unit's mount), scaled so that its RMS over time is angular_rms_deg (translation_rms_m). A narrow
// band is a mount resonance.
//
// Simulate happens in the cast (Effect::moved_pose): the renderer casts every column from the
// jittered pose, so a surface's range changes exactly as geometry says. Predict gives, for a plane
// at incidence theta and range r, with the jitter isotropic (sigma_a rad, sigma_t m per axis):
//   variance += (r tan(theta) sigma_a)^2 + (sigma_t / cos(theta))^2   (+ a fourth-order term)
//   bias     += r sigma_a^2 / cos(theta)^2   (second order: a tilted beam always reaches farther)
// (the beam's direction turns by the rotation's component across it, whose part in the plane of
// incidence has variance sigma_a^2; a translation moves the plane's distance by n . delta).
// No published vibration magnitudes for Ouster mounts: off unless a profile sets it.
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "effects/builtin_effects.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

constexpr uint32_t kUnitStream = 0x4531310Au;  // "E11\n": the mount's tones, apart from every noise stream
constexpr int kTones = 16;
constexpr double kDegree = std::numbers::pi / 180.0;

struct VibrationParameters {
  double angular_rms_deg = 0.02;
  double translation_rms_m = 0.0;
  double band_low_hz = 20.0;
  double band_high_hz = 200.0;
  double unit_seed = 0.0;
};

// One axis' band-limited noise: sum of a * sin(omega_k t + phase_k).
struct Tones {
  std::array<double, kTones> omega{}, phase{};
  double amplitude = 0.0;
  double at(double t) const {
    double sum = 0.0;
    for (int k = 0; k < kTones; ++k) sum += std::sin(omega[static_cast<size_t>(k)] * t + phase[static_cast<size_t>(k)]);
    return amplitude * sum;
  }
};

class Vibration final : public TabledEffect<Vibration, VibrationParameters> {
 public:
  using P = VibrationParameters;
  static constexpr std::string_view kName = "vibration";
  static constexpr std::array<ParameterSpec<P>, 5> kSpecs{{
      {"angular_rms_deg", &P::angular_rms_deg, {0.0, 1.0}},
      {"translation_rms_m", &P::translation_rms_m, {0.0, 0.05}},
      {"band_low_hz", &P::band_low_hz, {0.1, 10000.0}},
      {"band_high_hz", &P::band_high_hz, {0.1, 10000.0}},
      {"unit_seed", &P::unit_seed, {0.0, 4294967295.0}},
  }};
  static void check(const P& p, const Location& at) {
    if (!(p.band_high_hz > p.band_low_hz)) {
      at.child("band_high_hz")
          .fail("must be above band_low_hz (" + format_number(p.band_low_hz) + "), got " +
                format_number(p.band_high_hz));
    }
  }
  explicit Vibration(const P& p) : TabledEffect(p) {
    // A sinusoid of amplitude a has variance a^2 / 2: kTones of them at distinct frequencies sum
    // to the RMS asked for.
    const double per_tone = std::sqrt(2.0 / kTones);
    for (uint32_t axis = 0; axis < 6; ++axis) {
      Tones& tones = axes_[axis];
      tones.amplitude = per_tone * (axis < 3 ? p.angular_rms_deg * kDegree : p.translation_rms_m);
      for (uint32_t k = 0; k < kTones; ++k) {
        const RandomStream unit(static_cast<uint64_t>(p.unit_seed), PixelKey{0, axis, k}, kUnitStream);
        const double hz = p.band_low_hz + (p.band_high_hz - p.band_low_hz) * unit.uniform(0);
        tones.omega[k] = 2.0 * std::numbers::pi * hz;
        tones.phase[k] = 2.0 * std::numbers::pi * unit.uniform(1);
      }
    }
  }

  bool moves_sensor() const override { return params().angular_rms_deg > 0.0 || params().translation_rms_m > 0.0; }

  Pose moved_pose(const Pose& world_from_sensor, const ColumnContext& context) const override {
    const double t = context.time_s;
    const Eigen::Vector3d angle(axes_[0].at(t), axes_[1].at(t), axes_[2].at(t));
    const Eigen::Vector3d shift(axes_[3].at(t), axes_[4].at(t), axes_[5].at(t));
    const double norm = angle.norm();
    Pose jitter;  // sensor_from_jittered_sensor
    if (norm > 0.0) jitter.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(norm, angle / norm));
    jitter.translation = shift;
    return world_from_sensor * jitter;
  }

  void simulate(std::span<const IdealReturn>, const ColumnContext&, MeasuredColumn&) const override {}

  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    if (!ideal.hit()) return;
    const double sigma_a = params().angular_rms_deg * kDegree, sigma_t = params().translation_rms_m;
    const double c = std::clamp(static_cast<double>(ideal.cos_incidence), 1e-3, 1.0);
    const double r = ideal.range_m;
    const double tan_theta = std::sqrt(1.0 - c * c) / c;
    // r' / r = 1 / (1 + X) with X ~ N(0, s^2) the tilt's share: variance s^2 + 8 s^4 to fourth order
    // (it matters near the bounds: 1.5 % of the spread at 1 degree RMS and 74 degrees incidence).
    const double s2 = std::pow(tan_theta * sigma_a, 2);
    prediction.variance_m2 += r * r * (s2 + 8.0 * s2 * s2) + std::pow(sigma_t / c, 2);
    prediction.bias_m += r * sigma_a * sigma_a / (c * c);
  }

 private:
  std::array<Tones, 6> axes_;  // rotation about x, y, z (rad), then translation along them (m)
};

}  // namespace

std::unique_ptr<Effect> make_vibration(const nlohmann::json& params, const Location& at) {
  return Vibration::create(params, at);
}

EffectCard vibration_card() { return {.catalogue = "E11"}; }

}  // namespace lidartwin::effects_detail
