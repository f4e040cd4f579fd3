#pragma once
// The values an effect chain produces and predicts for one pixel.
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace lidartwin {

// One pixel as measured, in physical units (the renderer converts to protocol units).
struct Measurement {
  float range_m = 0.0f;  // 0 = no return
  float signal_photons = 0.0f;
  float near_ir_photons = 0.0f;
  float reflectivity = 0.0f;  // calibrated reflectivity byte value, 0..255
  float range2_m = 0.0f;      // second return (dual profiles), 0 = none
  float signal2_photons = 0.0f;
  float reflectivity2 = 0.0f;
};

// One column of Measurements as parallel arrays, one per quantity (structure of arrays): effects
// loop over the beams of plain float arrays, which the compiler vectorizes, where an array of
// 28-byte structs would be read with a stride (DESIGN.md "Speed": a few ns per pixel).
struct MeasuredColumn {
  MeasuredColumn() = default;
  explicit MeasuredColumn(size_t beams)
      : range_m(beams),
        signal_photons(beams),
        near_ir_photons(beams),
        reflectivity(beams),
        range2_m(beams),
        signal2_photons(beams),
        reflectivity2(beams),
        listed_(beams) {}

  size_t size() const { return range_m.size(); }

  // The beams with a return (range_m != 0) when the chain last listed them, in beam order. The
  // chain lists them before the first effect and again after any effect that may add returns
  // (Effect::adds_returns), so the list holds every return; returns since removed are in it with
  // range 0. Effects that act on returns only walk this list: from the drone's pose a fifth of a
  // column returns, and walking all 128 beams per effect cost more than the returns themselves.
  std::span<const uint32_t> listed_returns() const { return {listed_.data(), listed_count_}; }
  void list_returns() {
    listed_.resize(size());
    size_t n = 0;
    for (size_t beam = 0; beam < size(); ++beam) {  // without a branch: returns and misses interleave
      listed_[n] = static_cast<uint32_t>(beam);
      n += range_m[beam] != 0.0f;
    }
    listed_count_ = n;
  }
  Measurement operator[](size_t beam) const {
    return {range_m[beam],  signal_photons[beam],  near_ir_photons[beam], reflectivity[beam],
            range2_m[beam], signal2_photons[beam], reflectivity2[beam]};
  }

  std::vector<float> range_m;
  std::vector<float> signal_photons;
  std::vector<float> near_ir_photons;
  std::vector<float> reflectivity;
  std::vector<float> range2_m;
  std::vector<float> signal2_photons;
  std::vector<float> reflectivity2;

 private:
  std::vector<uint32_t> listed_;
  size_t listed_count_ = 0;
};

// The distribution of the measured range of one pixel given its ideal return, as the analysis
// uses it for likelihoods: a detection probability, and when detected a mixture of
// N(range + bias, variance) with weight (1 - outlier_mix) and a broad outlier component.
// When range limits apply, a detected range lies in [window_min_m, window_max_m]: the Gaussian is
// truncated there, and p_detect already includes its probability mass inside the window.
struct Prediction {
  double bias_m = 0.0;
  // The part of bias_m that the pixel's neighbours at the same place do not share: E10's per-beam
  // offsets and scales. A reference surface made of the sensor's own returns from neighbouring beams
  // (map mode) carries the rest of the bias, not this.
  double unshared_bias_m = 0.0;
  double variance_m2 = 0.0;
  double p_detect = 1.0;
  double outlier_mix = 0.0;
  double quantization_step_m = 0.0;  // 0 = continuous
  double window_min_m = 0.0;
  double window_max_m = std::numeric_limits<double>::infinity();
  double signal_photons = 0.0;   // expected SIGNAL (radiometry), for signal-dependent effects
  double near_ir_photons = 0.0;  // expected NEAR_IR (radiometry)
  // E6: with probability partner_mix the return comes from the edge partner's surface, its range
  // offset by partner_offset_m (the Gaussian above, shifted); p_second: the probability of a second
  // return (dual profiles, E15). E8 puts its halo returns there too, with their own spread: the
  // component's variance is variance_m2 + partner_extra_variance_m2 (what effects after it add to
  // variance_m2 they add to both, as their simulate adds it to whichever return comes first).
  double partner_mix = 0.0;
  double partner_offset_m = 0.0;
  double partner_extra_variance_m2 = 0.0;
  double p_second = 0.0;
  // E2's tails (signal_outliers): with probability tail_mix a detected return's range is drawn
  // about the same mean with tail_extra_variance_m2 more variance (what later effects add to
  // variance_m2 applies to both components).
  double tail_mix = 0.0;
  double tail_extra_variance_m2 = 0.0;
  // Photon (shot) noise: the variances of the reported SIGNAL and NEAR_IR about the expected
  // values above (photons^2; 0 = reported exactly).
  double signal_variance = 0.0;
  double near_ir_variance = 0.0;
  // E6's echoes, for the effects after it that read the signal. Where the footprint straddles a
  // depth step, where the edge lies (a draw per pixel) decides which echo is reported and how much
  // power it carries, and the effects that read that signal (dropout, E2's spread and tails) act
  // on each draw's own signal: their predictions are expectations over the edge's position, not
  // functions of the mean signal (which would make detection and the partner's share independent
  // where they are not: a dim oblique pixel is detected mostly when its bright partner wins).
  // Nodes of a quadrature over that position: the probability of each (given detection, once
  // dropout has weighed them), its signal as a factor of signal_photons (so effects that scale the
  // signal scale every node), and its range offset from the pixel's own surface (a merged echo's
  // power-weighted mean; the partner's step). The first own_echoes nodes are the pixel's own echo's
  // (its Gaussian), the rest the partner's (partner_mix). echo_count 0: one echo, signal_photons.
  struct Echo {
    float weight = 0.0f;
    float signal_factor = 1.0f;
    float offset_m = 0.0f;
  };
  static constexpr size_t kMaxEchoes = 8;
  std::array<Echo, kMaxEchoes> echoes{};
  uint8_t echo_count = 0;
  uint8_t own_echoes = 0;
};

// What the chain knows beyond the pixel: the random-stream key and the wire format's limits.
struct ColumnContext {
  uint64_t seed = 0;
  uint64_t frame = 0;
  uint32_t column = 0;          // measurement id
  float range_step_m = 0.001f;  // 0.001 (RNG19, LEGACY) or 0.008 (RNG15 profiles)
  float max_wire_range_m = 524.287f;
  // The largest SIGNAL and NEAR_IR the wire carries (0: the profile has no such field): RNG15's
  // 8-bit NEAR_IR, times 16, ends at 4080 photons.
  float max_wire_signal = 65535.0f;
  float max_wire_near_ir = 65535.0f;
  float near_ir_step = 1.0f;  // and its step (16 there)
  float signal_gain = 1.0f;   // signal_multiplier and lidar-mode integration (E18)
  double time_s = 0.0;        // the column's time since the capture (or stream) began: drift (E12)
  // The lidar mode's columns per rotation: measurement id `column` sits at encoder angle
  // 2 pi column / columns_per_frame (window sectors, E16). 0 = not known.
  uint32_t columns_per_frame = 0;
  double encoder_angle_deg() const {
    return columns_per_frame == 0 ? 0.0 : 360.0 * static_cast<double>(column) / static_cast<double>(columns_per_frame);
  }
};

}  // namespace lidartwin
