#pragma once
// Casts the beams of one column at one pose with Embree (16-ray coherent packets).
#include <span>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/caster/ideal_return.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

class ColumnCaster {
 public:
  ColumnCaster(const Scene& scene, const BeamGeometry& geometry);
  // out.size() == geometry.rows(). Thread-safe (const): workers cast different columns at once.
  void cast(int measurement_id, const Pose& world_from_sensor, std::span<IdealReturn> out) const;

 private:
  const Scene& scene_;
  const BeamGeometry& geometry_;
};

}  // namespace lidartwin
