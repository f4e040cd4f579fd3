// The SLAM yard (scenes/yard.glb): a compact process yard around a low drone lap, made so that a
// lidar odometry experiment measures the sensor, not the scene. From the lap, 5 m up, structure
// stands within 10-25 m on every side: a process module inside the loop with a column at each
// end, a pipe rack along the south side, storage tanks along the north, a warehouse to the west,
// a sphere and drums to the east; light poles break up the long faces. The plant (plant.glb) is
// too open for this from 6-18 m up (few non-ground returns, little along-track constraint).
#include <numbers>

#include "generators.h"
#include "plant_assets.h"

namespace lidartwin::scenegen {
namespace {

constexpr double kPi = std::numbers::pi;

Parts yard_grounds(const PlantMaterials& m) {
  Parts p;
  p[m.gravel].append(quad({-120, -100, 0}, {120, -100, 0}, {120, 100, 0}, {-120, 100, 0}));
  p[m.concrete].append(box({-60, -45, 0}, {60, 45, 0.05f}));
  p[m.asphalt].append(box({-3, -24, 0}, {3, -16, 0.08f}));  // the take-off pad on the lap
  return p;
}

}  // namespace

GlbWriter build_yard() {
  GlbWriter out;
  const PlantMaterials m = add_plant_materials(out);
  place(out, yard_grounds(m), "grounds", {{0, 0, 0, 0}});
  place(out, process_module(m), "process_module", {{0, 0, 0, 0}});
  place(out, column_tower(m, 2.0f, 30.0f), "column", {{-21, 6, 0, 0.4}, {21, -6, 0, 2.2}});
  place(out, horizontal_drum(m, 1.5f, 8.0f), "drum_inside", {{-21, -7, 0, kPi / 2}, {21, 7, 0, kPi / 2}});
  place(out, pipe_rack(m, 84.0f, 2, 8), "south_rack", {{-42, -31, 0, 0}});
  place(out, storage_tank(m, 7.0f, 12.0f, false), "tank", {{-26, 33, 0, 0.5}, {26, 33, 0, 3.0}});
  place(out, storage_tank(m, 6.0f, 15.0f, true), "tank_dome", {{0, 32, 0, 1.7}});
  place(out, building(m, {12, 30, 8}), "warehouse", {{-42, 0, 0, 0}});
  place(out, spherical_tank(m, 6.0f), "sphere", {{42, 10, 0, 0}});
  place(out, horizontal_drum(m, 1.8f, 10.0f), "drum_east", {{41, -10, 0, kPi / 2}});
  std::vector<Eigen::Vector4d> poles;
  for (double x = -48; x <= 48; x += 16) poles.push_back({x, 24, 0, kPi / 2});
  for (double y = -12; y <= 12; y += 12) poles.push_back({34, y, 0, 0});
  place(out, light_pole(m), "light_pole", poles);
  place(out, sign(m), "retro_sign", {{-10, -25, 0, kPi}, {14, 24, 0, 0}});
  return out;
}

}  // namespace lidartwin::scenegen
