#pragma once
// One physical effect, used in both directions from the same parameters (DESIGN.md "One model,
// two directions"): simulate draws measured values, predict gives their distribution.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/caster/ideal_return.h"
#include "lidartwin/effects/measurement.h"
#include "lidartwin/random/counter_rng.h"

namespace lidartwin {

struct EffectParameter {
  std::string name;
  double value = 0.0;
  double lower = 0.0;  // bounds for fitting and validation
  double upper = 0.0;
};

class Effect {
 public:
  virtual ~Effect() = default;
  virtual std::string_view name() const = 0;

  // Applies the effect to one column in place. `measured` holds what earlier effects produced
  // (the chain starts it from the ideal returns). Random numbers come only from stream().
  virtual void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                        std::span<Measurement> measured) const = 0;
  // Folds this effect into the predicted distribution of one pixel's measured range.
  virtual void predict(const IdealReturn& ideal, const ColumnContext& context, Prediction& prediction) const = 0;

  // Parameters, for JSON output and maximum-likelihood fitting.
  virtual std::vector<EffectParameter> parameters() const = 0;
  // A copy with new parameter values (same order as parameters()); throws InputError if out of bounds.
  virtual std::unique_ptr<Effect> with_parameters(std::span<const double> values) const = 0;
  nlohmann::json to_json() const;  // {"name": ..., <parameter>: value, ...}

  void set_stream_id(uint32_t id) { stream_id_ = id; }

 protected:
  RandomStream stream(const ColumnContext& context, uint32_t beam) const {
    return RandomStream(context.seed, PixelKey{context.frame, context.column, beam}, stream_id_);
  }

 private:
  uint32_t stream_id_ = 0;
};

}  // namespace lidartwin
