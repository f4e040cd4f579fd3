#pragma once
// Zero-mean Gaussian noise along the beam with a range-dependent sigma (E1; the paper's Section
// III model and its piecewise datasheet form). Derived supplies `double sigma(float range_m) const`
// of the TRUE range; simulate and predict are written once here so they cannot drift apart.
#include <cstdint>
#include <span>

#include "lidartwin/effects/effect.h"

namespace lidartwin {

template <class Derived, class Base>
class GaussianRangeNoise : public Base {
 public:
  using Base::Base;

  void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                MeasuredColumn& measured) const override {
    const auto& self = static_cast<const Derived&>(*this);
    const ColumnStreams streams = this->column_streams(context);
    float* range = measured.range_m.data();
    for (const uint32_t beam : measured.listed_returns()) {
      if (range[beam] == 0.0f) continue;  // no longer a return (a negative noisy range still counts)
      const double noise = self.sigma(ideal[beam].range_m) * streams(beam).normal_ziggurat(0);
      range[beam] = static_cast<float>(static_cast<double>(range[beam]) + noise);
    }
  }

  bool adds_returns() const override { return false; }

  void predict(const IdealReturn& ideal, const ColumnContext&, Prediction& prediction) const override {
    const double s = static_cast<const Derived&>(*this).sigma(ideal.range_m);
    prediction.variance_m2 += s * s;
  }
};

}  // namespace lidartwin
