// The industrial plant (scenes/plant.glb), after the paper's refinery (Section II, Fig. 2): a tank
// farm in the west, process modules with columns around two pipe racks, spheres, drums,
// buildings and a flare in the east, roads, light poles, retroreflective signs and a fence. The
// layout is fixed; the little variation inside modules comes from unit_hash, so it is deterministic.
// Reflectivities are typical 865 nm diffuse values (paints, concrete, asphalt), not measurements.
#include <cmath>
#include <numbers>

#include "generators.h"
#include "plant_assets.h"

namespace lidartwin::scenegen {

PlantMaterials add_plant_materials(GlbWriter& out) {
  const auto add = [&out](const char* name, double rho, std::array<double, 3> color, double specular = 0.0,
                          bool retro = false) {
    return out.add_material({name, rho, retro, specular, color});
  };
  PlantMaterials m{};
  m.gravel = add("gravel", 0.2, {0.45, 0.43, 0.4});
  m.asphalt = add("asphalt", 0.08, {0.15, 0.15, 0.15});
  m.concrete = add("concrete", 0.35, {0.65, 0.65, 0.62});
  m.tank_white = add("tank_white_paint", 0.8, {0.92, 0.92, 0.9});
  m.tank_grey = add("vessel_grey_paint", 0.45, {0.55, 0.57, 0.6});
  m.roof_grey = add("tank_roof_grey", 0.3, {0.4, 0.4, 0.42});
  m.steel_galvanized = add("galvanized_steel", 0.4, {0.6, 0.62, 0.64}, 0.3);
  m.steel_yellow = add("yellow_structural_paint", 0.55, {0.9, 0.75, 0.1});
  m.steel_red = add("red_oxide_paint", 0.25, {0.55, 0.15, 0.1});
  m.grating = add("floor_grating", 0.3, {0.5, 0.5, 0.5});
  m.pipe_aluminium = add("aluminium_insulation_cladding", 0.6, {0.8, 0.8, 0.82}, 0.5);
  m.pipe_black = add("black_pipe_paint", 0.05, {0.08, 0.08, 0.08});
  m.pipe_green = add("green_pipe_paint", 0.25, {0.2, 0.45, 0.25});
  m.wall_sheet = add("building_wall_sheet", 0.5, {0.75, 0.78, 0.8});
  m.roof_sheet = add("building_roof_sheet", 0.3, {0.35, 0.4, 0.45});
  m.glass = add("window_glass", 0.06, {0.2, 0.3, 0.35}, 0.9);
  m.door = add("door_paint", 0.3, {0.3, 0.35, 0.6});
  m.sign_retro = add("retroreflective_sign", 0.9, {0.95, 0.85, 0.1}, 0.0, true);
  m.sign_post = add("sign_post", 0.4, {0.6, 0.6, 0.6});
  return m;
}

void place(GlbWriter& out, const Parts& parts, const std::string& name, const std::vector<Eigen::Vector4d>& where) {
  const int mesh = out.add_mesh(name, parts.list());
  for (size_t i = 0; i < where.size(); ++i) {
    out.add_instance(mesh, name + "_" + std::to_string(i), where[i].head<3>(), where[i].w());
  }
}

namespace {

constexpr double kPi = std::numbers::pi;
using V = Eigen::Vector3f;

// Ground, roads, the tank-farm bund and the pads under the process area.
Parts grounds(const PlantMaterials& m) {
  Parts p;
  p[m.gravel].append(quad({-350, -250, 0}, {350, -250, 0}, {350, 250, 0}, {-350, 250, 0}));
  for (const float y : {-92.0f, 92.0f}) p[m.asphalt].append(box({-170, y - 4, 0}, {170, y + 4, 0.03f}));
  for (const float x : {-65.0f, 135.0f}) p[m.asphalt].append(box({x - 4, -88, 0}, {x + 4, 88, 0.03f}));
  p[m.concrete].append(box({-50, -66, 0}, {125, 66, 0.05f}));
  const float bund[4][4] = {
      {-148, -78, -78, -77.6f}, {-148, 77.6f, -78, 78}, {-148, -78, -147.6f, 78}, {-78.4f, -78, -78, 78}};
  for (const auto& b : bund) p[m.concrete].append(box({b[0], b[1], 0}, {b[2], b[3], 1.5f}));
  p[m.concrete].append(box({-148, -0.2f, 0}, {-78, 0.2f, 1.5f}));
  return p;
}

void tank_farm(GlbWriter& out, const PlantMaterials& m) {
  place(out, storage_tank(m, 12.0f, 14.0f, false), "tank_a",
        {{-130, -60, 0, 0.3}, {-130, 20, 0, 2.1}, {-95, -20, 0, 4.0}});
  place(out, storage_tank(m, 11.0f, 16.0f, true), "tank_b",
        {{-130, 60, 0, 1.2}, {-95, -60, 0, 5.1}, {-95, 60, 0, 3.3}});
  place(out, storage_tank(m, 10.0f, 12.0f, false), "tank_c", {{-130, -20, 0, 0.8}, {-95, 20, 0, 2.7}});
  Parts transfer;  // tank outlets up and over the road onto the main rack
  for (const float y : {-60.0f, -20.0f, 20.0f, 60.0f}) {
    const float side = y < 0 ? -1.0f : 1.0f;
    Mesh& pipe = transfer[m.pipe_black];
    pipe.append(tube({-82, y, 0.8f}, {-82, y, 6.0f}, 0.3f, 16));
    pipe.append(tube({-82, y, 6.0f}, {-55, y, 6.0f}, 0.3f, 16));
    pipe.append(tube({-55, y, 6.0f}, {-55, side * 3.0f, 6.0f}, 0.3f, 16));
    transfer[m.steel_galvanized].append(box_at({-70, y, 3.0f}, {0.3f, 0.3f, 6.0f}));
  }
  place(out, transfer, "transfer_lines", {{0, 0, 0, 0}});
}

void process_area(GlbWriter& out, const PlantMaterials& m) {
  place(out, pipe_rack(m, 180.0f, 3, 10), "main_rack", {{-55, 0, 0, 0}});
  place(out, pipe_rack(m, 66.0f, 2, 8), "cross_rack", {{15, -75, 0, kPi / 2}, {15, 9, 0, kPi / 2}});
  place(out, process_module(m), "process_module",
        {{-22, 30, 0, 0}, {-22, -30, 0, kPi}, {48, 30, 0, 0}, {48, -30, 0, kPi}});
  const double towers[6][4] = {{-30, 55, 2.5, 45}, {-14, 56, 2.0, 38},  {40, 55, 3.0, 42},
                               {56, 56, 1.8, 30},  {-25, -55, 2.2, 35}, {45, -56, 2.6, 40}};
  for (const auto& t : towers) {
    place(out, column_tower(m, static_cast<float>(t[2]), static_cast<float>(t[3])), "column",
          {{t[0], t[1], 0, unit_hash(static_cast<uint64_t>(t[3]), 3) * 2 * kPi}});
  }
  place(out, horizontal_drum(m, 1.8f, 12.0f), "drum",
        {{82, 14, 0, 0}, {82, 24, 0, 0}, {82, -14, 0, 0}, {82, -24, 0, 0}});
  place(out, spherical_tank(m, 8.0f), "sphere", {{82, 52, 0, 0}, {82, -52, 0, 0.3}});
  place(out, flare_stack(m, 55.0f), "flare", {{118, 62, 0, 0}});
}

void buildings_and_furniture(GlbWriter& out, const PlantMaterials& m) {
  place(out, building(m, {20, 14, 5}), "control_room", {{110, 30, 0, 0}});
  place(out, building(m, {24, 18, 9}), "warehouse", {{110, -35, 0, 0}});
  place(out, building(m, {20, 12, 6}), "workshop", {{-20, -78, 0, 0}});
  place(out, building(m, {14, 10, 5}), "substation", {{40, 78, 0, kPi}});
  place(out, fence(m, {160, 110}, 6), "fence", {{0, 0, 0, 0}});
  std::vector<Eigen::Vector4d> poles;
  for (double x = -150; x <= 150; x += 30) {
    poles.push_back({x, -87, 0, -kPi / 2});  // arms reach over the road
    poles.push_back({x, 87, 0, kPi / 2});
  }
  for (double y = -60; y <= 60; y += 30) poles.push_back({-60, y, 0, kPi});
  place(out, light_pole(m), "light_pole", poles);
  // Sign panels face -y in their frame; yaw turns them towards the road they serve.
  place(out, sign(m), "retro_sign",
        {{-60, -86, 0, 0},
         {-60, 86, 0, kPi},
         {130, -86, 0, 0},
         {130, 86, 0, kPi},
         {0, -86, 0, 0},
         {0, 86, 0, kPi},
         {-76, -40, 0, kPi / 2},
         {-76, 40, 0, kPi / 2},
         {-5, 16, 0, 0},
         {30, -16, 0, kPi},
         {97, -30, 0, -kPi / 2},
         {97, -40, 0, -kPi / 2}});
}

}  // namespace

GlbWriter build_plant() {
  GlbWriter out;
  const PlantMaterials m = add_plant_materials(out);
  place(out, grounds(m), "grounds", {{0, 0, 0, 0}});
  tank_farm(out, m);
  process_area(out, m);
  buildings_and_furniture(out, m);
  return out;
}

}  // namespace lidartwin::scenegen
