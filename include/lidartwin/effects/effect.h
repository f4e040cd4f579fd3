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
#include "lidartwin/pose/pose.h"
#include "lidartwin/random/counter_rng.h"

namespace lidartwin {

struct EffectParameter {
  std::string name;  // a key of the effect's JSON object, or a JSON pointer below it ("points_m/2/1")
  double value = 0.0;
  double lower = 0.0;  // bounds for fitting and validation
  double upper = 0.0;
  bool fixed = false;  // structural (e.g. a knot's range): validated, but not for fitting
};

class Effect {
 public:
  virtual ~Effect() = default;
  virtual std::string_view name() const = 0;

  // Applies the effect to one column in place. `measured` holds what earlier effects produced
  // (the chain starts it from the ideal returns); measured.size() == ideal.size(). Random numbers
  // come only from stream() / column_streams().
  virtual void simulate(std::span<const IdealReturn> ideal, const ColumnContext& context,
                        MeasuredColumn& measured) const = 0;
  // Folds this effect into the predicted distribution of one pixel's measured range.
  virtual void predict(const IdealReturn& ideal, const ColumnContext& context, Prediction& prediction) const = 0;

  // Parameters, for JSON output and maximum-likelihood fitting.
  virtual std::vector<EffectParameter> parameters() const = 0;
  // A copy with new parameter values (same order as parameters()); throws InputError if out of bounds.
  virtual std::unique_ptr<Effect> with_parameters(std::span<const double> values) const = 0;
  nlohmann::json to_json() const;  // {"name": ..., <parameter>: value, ...}

  // Whether simulate may give a pixel without a return one (false alarms, fog, halo...): the chain
  // then lists the returns again (MeasuredColumn::listed_returns). Effects that only change or
  // remove returns say false.
  virtual bool adds_returns() const { return true; }
  // Effects that must come earlier in a chain, e.g. dropout reads the signal radiometry produces.
  virtual std::vector<std::string_view> prerequisites() const { return {}; }
  // Whether it reads IdealReturn's partner_* fields, which the caster then fills (E6).
  virtual bool needs_edge_partners() const { return false; }
  // Effects that move the sensor (vibration, E11) simulate through the cast: the renderer casts
  // each column from moved_pose(the column's pose); their simulate() leaves the pixels alone and
  // predict() folds in what the motion does to a surface's range. A pure function of the pose
  // and the column's context (time), so any thread count casts the same rays.
  virtual bool moves_sensor() const { return false; }
  virtual Pose moved_pose(const Pose& world_from_sensor, const ColumnContext&) const { return world_from_sensor; }

  void set_stream_id(uint32_t id) { stream_id_ = id; }
  uint32_t stream_id() const { return stream_id_; }

 protected:
  RandomStream stream(const ColumnContext& context, uint32_t beam) const {
    return RandomStream(context.seed, PixelKey{context.frame, context.column, beam}, stream_id_);
  }
  // The same streams for a whole column, keyed once per column: streams(beam) == stream(context, beam).
  ColumnStreams column_streams(const ColumnContext& context) const {
    return ColumnStreams(context.seed, context.frame, context.column, stream_id_);
  }

 private:
  uint32_t stream_id_ = 0;
};

}  // namespace lidartwin
