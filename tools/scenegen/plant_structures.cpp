// Steel structures of the plant: process modules, pipe racks, buildings and the fence.
#include <cmath>
#include <numbers>

#include "plant_assets.h"

namespace lidartwin::scenegen {
namespace {

using V = Eigen::Vector3f;

Eigen::Affine3f at(const V& p) { return Eigen::Affine3f(Eigen::Translation3f(p)); }
Eigen::Affine3f at(float x, float y, float z) { return at(V(x, y, z)); }

// A member (beam, column, brace) between two points with a square section.
Mesh member(const V& a, const V& b, float section) {
  const V lower = a.cwiseMin(b) - V::Constant(section / 2), upper = a.cwiseMax(b) + V::Constant(section / 2);
  const auto moving = ((a - b).cwiseAbs().array() > 1e-3f).count();
  return moving > 1 ? tube(a, b, section / 2, 6) : box(lower, upper);  // diagonals are round
}

// Module frame: 6 m grid, 30 × 24 m, floors at 6 and 12 m, roof beams at 18 m.
void module_frame(Parts& parts, const PlantMaterials& m) {
  for (float x = -15; x <= 15; x += 6) {
    for (float y = -12; y <= 12; y += 6) parts[m.steel_yellow].append(member({x, y, 0}, {x, y, 18}, 0.4f));
  }
  for (const float z : {6.0f, 12.0f, 18.0f}) {
    for (float y = -12; y <= 12; y += 6) parts[m.steel_yellow].append(member({-15, y, z}, {15, y, z}, 0.35f));
    for (float x = -15; x <= 15; x += 6) parts[m.steel_yellow].append(member({x, -12, z}, {x, 12, z}, 0.35f));
    if (z > 15) continue;
    for (float x = -15; x < 15; x += 6) {  // grating floors, with one bay left open for the vessels
      for (float y = -12; y < 12; y += 6) {
        if (x > -4 && x < 2 && y > -7) continue;
        parts[m.grating].append(box({x + 0.2f, y + 0.2f, z + 0.18f}, {x + 5.8f, y + 5.8f, z + 0.22f}));
      }
    }
    for (float x = -15; x <= 15; x += 1.5f) {  // edge rail posts, long sides
      for (const float y : {-12.0f, 12.0f})
        parts[m.steel_yellow].append(box_at({x, y, z + 0.75f}, {0.05f, 0.05f, 1.1f}));
    }
  }
  for (const float y : {-12.0f, 12.0f}) {  // X bracing on the long faces
    for (float x = -15; x < 15; x += 6) {
      for (const float z : {0.0f, 6.0f, 12.0f}) {
        parts[m.steel_galvanized].append(member({x, y, z}, {x + 6, y, z + 6}, 0.2f));
        parts[m.steel_galvanized].append(member({x + 6, y, z}, {x, y, z + 6}, 0.2f));
      }
    }
  }
}

// Vessels, exchangers, pumps and air coolers.
void module_equipment(Parts& parts, const PlantMaterials& m) {
  for (int k = 0; k < 3; ++k) {
    const V base(-3.0f + 3.0f * static_cast<float>(k % 2), -3.0f + 5.0f * static_cast<float>(k) / 2.0f, 0.5f);
    parts[m.tank_grey].append(cylinder(1.3f, 15.0f, 40, false, false), at(base));
    parts[m.tank_grey].append(dome(1.3f, 0.6f, 40, 5), at(base + V(0, 0, 15)));
  }
  for (int k = 0; k < 4; ++k) {  // shell-and-tube exchangers on the first floor
    const float y = -10.0f + 2.2f * static_cast<float>(k);
    parts[m.pipe_green].append(capsule_x(0.6f, 6.0f, 32, 6), at(8.0f, y, 7.2f));
  }
  for (int k = 0; k < 10; ++k) {  // pumps at grade
    const V p(-13.0f + 3.0f * static_cast<float>(k), 8.5f, 0.0f);
    parts[m.concrete].append(box(p + V(-0.6f, -0.4f, 0), p + V(0.6f, 0.4f, 0.3f)));
    parts[m.steel_red].append(capsule_x(0.25f, 0.7f, 16, 3), at(p + V(-0.2f, 0, 0.65f)));
    parts[m.steel_galvanized].append(cylinder(0.3f, 0.5f, 16, false, true), at(p + V(0.4f, 0, 0.3f)));
  }
  for (int k = 0; k < 5; ++k) {  // air cooler fans on the roof
    const V c(-12.0f + 6.0f * static_cast<float>(k), 0.0f, 18.2f);
    parts[m.grating].append(box(c + V(-2.8f, -5.5f, 0), c + V(2.8f, 5.5f, 0.3f)));
    for (const float y : {-3.0f, 3.0f})
      parts[m.steel_galvanized].append(cylinder(1.3f, 0.9f, 32, false, false), at(c + V(0, y, 0.3f)));
  }
}

// Pipe runs between equipment: deterministic L-shaped routes inside the frame.
void module_piping(Parts& parts, const PlantMaterials& m) {
  const int materials[3] = {m.pipe_aluminium, m.pipe_black, m.pipe_green};
  for (uint64_t k = 0; k < 125; ++k) {
    const auto u = [k](uint64_t salt) { return static_cast<float>(unit_hash(k, salt)); };
    const float z = (u(1) < 0.5f ? 3.0f : 9.0f) + 2.0f * u(2);
    const V a(-14.0f + 28.0f * u(3), -11.0f + 22.0f * u(4), z);
    const V b(-14.0f + 28.0f * u(5), a.y(), z), c(b.x(), -11.0f + 22.0f * u(6), z + (u(7) < 0.3f ? 3.0f : 0.0f));
    const float radius = 0.05f + 0.2f * u(8) * u(8);
    Mesh& pipe = parts[materials[k % 3]];
    pipe.append(tube(a, b, radius, 12));
    pipe.append(tube(b, V(b.x(), b.y(), c.z()), radius, 12));
    pipe.append(tube(V(b.x(), b.y(), c.z()), c, radius, 12));
  }
}

// Stair flights at the west end, ground → 6 → 12 m.
void module_stairs(Parts& parts, const PlantMaterials& m) {
  for (int flight = 0; flight < 2; ++flight) {
    const float z0 = 6.0f * static_cast<float>(flight);
    for (int s = 0; s < 30; ++s) {
      const float t = static_cast<float>(s) / 30.0f;
      parts[m.steel_galvanized].append(box_at({-17.0f, -8.0f + 8.0f * t, z0 + 6.0f * t}, {1.0f, 0.28f, 0.05f}));
    }
    for (const float x : {-17.5f, -16.5f}) {
      parts[m.steel_yellow].append(tube({x, -8.0f, z0}, {x, 0.0f, z0 + 6.0f}, 0.05f, 6));
    }
  }
}

}  // namespace

Parts process_module(const PlantMaterials& m) {
  Parts parts;
  parts[m.concrete].append(box({-16, -13, -0.1f}, {16, 13, 0.2f}));
  module_frame(parts, m);
  module_equipment(parts, m);
  module_piping(parts, m);
  module_stairs(parts, m);
  return parts;
}

Parts pipe_rack(const PlantMaterials& m, float length, int levels, int pipes_per_level) {
  Parts parts;
  const float top = 2.0f + 3.0f * static_cast<float>(levels);
  for (float x = 0; x <= length + 0.01f; x += 6.0f) {
    for (const float y : {-4.0f, 4.0f}) {
      parts[m.steel_galvanized].append(member({x, y, 0}, {x, y, top}, 0.35f));
      parts[m.concrete].append(box({x - 0.5f, y - 0.5f, 0}, {x + 0.5f, y + 0.5f, 0.3f}));
    }
    for (int level = 0; level < levels; ++level) {
      const float z = 5.0f + 3.0f * static_cast<float>(level);
      parts[m.steel_galvanized].append(member({x, -4, z}, {x, 4, z}, 0.3f));
      for (int p = 0; p < pipes_per_level; ++p) {  // pipe shoes
        const float y = -3.5f + 7.0f * static_cast<float>(p) / static_cast<float>(pipes_per_level - 1);
        parts[m.steel_galvanized].append(box({x - 0.15f, y - 0.1f, z + 0.15f}, {x + 0.15f, y + 0.1f, z + 0.3f}));
      }
    }
  }
  for (int level = 0; level < levels; ++level) {
    const float z = 5.0f + 3.0f * static_cast<float>(level);
    for (const float y : {-4.0f, 4.0f}) parts[m.steel_galvanized].append(member({0, y, z}, {length, y, z}, 0.3f));
    for (int p = 0; p < pipes_per_level; ++p) {
      const float radius = 0.08f + 0.3f * static_cast<float>(unit_hash(static_cast<uint64_t>(level * 31 + p), 7));
      const float y = -3.5f + 7.0f * static_cast<float>(p) / static_cast<float>(pipes_per_level - 1);
      const int material = (p + level) % 3 == 0 ? m.pipe_aluminium : (p % 2 == 0 ? m.pipe_black : m.pipe_green);
      parts[material].append(tube({-1.0f, y, z + 0.3f + radius}, {length + 1.0f, y, z + 0.3f + radius}, radius, 16));
    }
  }
  return parts;
}

Parts building(const PlantMaterials& m, const Eigen::Vector3f& size) {
  Parts parts;
  const V half(size.x() / 2, size.y() / 2, 0.0f);
  parts[m.wall_sheet].append(box(-half, half + V(0, 0, size.z())));
  parts[m.roof_sheet].append(box(-half + V(-0.3f, -0.3f, size.z()), half + V(0.3f, 0.3f, size.z() + 0.3f)));
  for (float x = -half.x() + 2.0f; x < half.x() - 1.5f; x += 3.0f) {  // windows on both long sides
    for (const float y : {-half.y() - 0.02f, half.y() + 0.02f}) {
      parts[m.glass].append(box({x, y - 0.01f, 1.0f}, {x + 1.6f, y + 0.01f, std::min(2.4f, size.z() - 0.5f)}));
    }
  }
  parts[m.door].append(box({-half.x() - 0.05f, -1.5f, 0}, {-half.x() + 0.01f, 1.5f, std::min(4.0f, size.z() - 0.5f)}));
  parts[m.steel_galvanized].append(box_at({half.x() * 0.4f, 0, size.z() + 1.0f}, {3.0f, 2.0f, 1.4f}));  // HVAC
  return parts;
}

Parts fence(const PlantMaterials& m, const Eigen::Vector2f& half, float gate) {
  Parts parts;
  const auto side = [&](const V& from, const V& to) {
    const float length = (to - from).norm();
    const int spans = static_cast<int>(std::ceil(length / 3.0f));
    for (int i = 0; i < spans; ++i) {
      const V a = from + (to - from) * static_cast<float>(i) / static_cast<float>(spans);
      const V b = from + (to - from) * static_cast<float>(i + 1) / static_cast<float>(spans);
      if (std::abs(a.x()) < gate || std::abs(a.y()) < gate) continue;
      parts[m.steel_galvanized].append(member(a, a + V(0, 0, 2.4f), 0.08f));
      for (const float z : {0.3f, 2.3f})
        parts[m.steel_galvanized].append(member(a + V(0, 0, z), b + V(0, 0, z), 0.05f));
    }
  };
  const V c00(-half.x(), -half.y(), 0), c10(half.x(), -half.y(), 0), c11(half.x(), half.y(), 0),
      c01(-half.x(), half.y(), 0);
  side(c00, c10);
  side(c10, c11);
  side(c11, c01);
  side(c01, c00);
  return parts;
}

}  // namespace lidartwin::scenegen
