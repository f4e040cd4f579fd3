// E2's tails (lidar-physics.md "Signal/reflectivity-dependent precision", and 3.3's "second
// Gaussian" outlier component): at low signal the peak the sensor finds in its photon histogram is
// now and then not the pulse's centre but a noise bump beside it, so the range error is Gaussian
// most of the time and much wider sometimes, the more often the weaker the return:
//   P(tail) = probability / (1 + S / half_signal_photons),   range += N(0, sigma_m^2) in the tail
// with S the expected signal (radiometry's SIGNAL, photons). Measured on a real motionless OS-0-128
// (crc_test.pcap, two frames at 1-2 m): returns of REFLECTIVITY below 10 differ between the frames
// by 3-20 cm a fifth of the time, bright ones almost never. Off by default (probability 0): no
// published value; `fit` sets it from a capture.
#include <algorithm>
#include <cmath>

#include "effects/builtin_effects.h"
#include "effects/echo_quadrature.h"
#include "effects/parameters.h"

namespace lidartwin::effects_detail {
namespace {

struct SignalOutlierParameters {
  double probability = 0.0;           // the tail's share as the signal goes to 0
  double half_signal_photons = 10.0;  // the signal at which it is half that
  double sigma_m = 0.1;               // the tail's spread beyond the return's own
};

class SignalOutliers final : public TabledEffect<SignalOutliers, SignalOutlierParameters> {
 public:
  using P = SignalOutlierParameters;
  static constexpr std::string_view kName = "signal_outliers";
  static constexpr std::array<ParameterSpec<P>, 3> kSpecs{{
      {"probability", &P::probability, {0.0, 1.0}},
      {"half_signal_photons", &P::half_signal_photons, {1e-3, 1e6}},
      {"sigma_m", &P::sigma_m, {1e-4, 10.0}},
  }};
  using TabledEffect::TabledEffect;

  std::vector<std::string_view> prerequisites() const override { return {"radiometry"}; }
  bool adds_returns() const override { return false; }

  // The same arithmetic serves both directions.
  double share(double signal) const {
    return params().probability / (1.0 + std::max(signal, 0.0) / params().half_signal_photons);
  }

  void simulate(std::span<const IdealReturn>, const ColumnContext& context, MeasuredColumn& measured) const override {
    if (params().probability <= 0.0) return;
    const ColumnStreams streams = column_streams(context);
    float* range = measured.range_m.data();
    for (const uint32_t beam : measured.listed_returns()) {
      if (range[beam] == 0.0f) continue;
      const RandomStream stream = streams(beam);
      if (stream.uniform(0) >= share(measured.signal_photons[beam])) continue;
      range[beam] = static_cast<float>(static_cast<double>(range[beam]) + params().sigma_m * stream.normal_ziggurat(1));
    }
  }

  // The tail is a second component about the same mean; what later effects add to the spread
  // (quantization, the window's limits) applies to both, as their simulate applies to any return.
  // Composed with a tail already there (two such effects), the shares add and the extra variances
  // are weighed by them.
  // Where E6 splits the footprint, the share is the mean over the pixel's own echoes
  // (echo_quadrature.h); a partner's echo's tails are not modelled (it lies a depth step away,
  // beyond the pixel's own Gaussian whatever its spread).
  void predict(const IdealReturn&, const ColumnContext&, Prediction& prediction) const override {
    const double add = prediction.echo_count > 0
                           ? echo_means(prediction, [this](double signal) { return share(signal); }).own
                           : share(prediction.signal_photons);
    if (add <= 0.0) return;
    const double extra = params().sigma_m * params().sigma_m;
    const double total = std::min(prediction.tail_mix + add, 1.0);
    prediction.tail_extra_variance_m2 =
        (prediction.tail_mix * prediction.tail_extra_variance_m2 + (total - prediction.tail_mix) * extra) / total;
    prediction.tail_mix = total;
  }
};

}  // namespace

std::unique_ptr<Effect> make_signal_outliers(const nlohmann::json& params, const Location& at) {
  return SignalOutliers::create(params, at);
}

// As a missing effect: how often at low signal (a minority of the returns, at most half: when every
// weak return would be in the tail, the spread is E2's own, which is a candidate of its own;
// against a map's references, whose errors are heavier-tailed than Gaussian, the two otherwise
// tie, the tails at a share of 1), and how wide.
EffectCard signal_outliers_card() {
  return {.catalogue = "E2",
          .candidate = true,
          .fit = {{"probability", 0.05, 0.05, {}, 0.5}, {"half_signal_photons", 10.0, 10.0}, {"sigma_m", 0.1, 0.05}}};
}

}  // namespace lidartwin::effects_detail
