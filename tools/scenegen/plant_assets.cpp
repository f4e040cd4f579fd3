// Round equipment of the plant: storage tanks, columns, spheres, drums, flare, signs and poles.
// Sizes are typical refinery dimensions (API 650 tanks tens of metres across, columns 30–45 m).
#include <cmath>
#include <numbers>

#include "plant_assets.h"

namespace lidartwin::scenegen {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
using V = Eigen::Vector3f;

Eigen::Affine3f at(float x, float y, float z, float yaw = 0.0f) {
  return Eigen::Translation3f(x, y, z) * Eigen::AngleAxisf(yaw, V::UnitZ());
}

// Guard rail around a circle: posts every ~2 m plus top and knee rails.
void ring_rail(Mesh& mesh, float radius, float z, int segments) {
  mesh.append(torus(radius, 0.03f, segments, 4), at(0, 0, z + 1.1f));
  mesh.append(torus(radius, 0.025f, segments, 4), at(0, 0, z + 0.55f));
  const int posts = std::max(6, static_cast<int>(2.0f * kPi * radius / 2.0f));
  for (int i = 0; i < posts; ++i) {
    const float a = 2.0f * kPi * static_cast<float>(i) / static_cast<float>(posts);
    mesh.append(box_at({radius * std::cos(a), radius * std::sin(a), z + 0.55f}, {0.05f, 0.05f, 1.1f}, a));
  }
}

// Vertical ladder at azimuth `a` on a shell of `radius`, from z0 to z1: rails and rungs every 0.3 m.
void ladder(Mesh& mesh, float radius, float a, float z0, float z1) {
  const V out(std::cos(a), std::sin(a), 0.0f), side(-std::sin(a), std::cos(a), 0.0f);
  const V base = (radius + 0.25f) * out;
  for (const float s : {-0.22f, 0.22f}) {
    mesh.append(tube(base + s * side + V(0, 0, z0), base + s * side + V(0, 0, z1), 0.03f, 6));
  }
  for (float z = z0 + 0.3f; z < z1; z += 0.3f) {
    const V c = base + V(0, 0, z);
    mesh.append(box_at(c, {0.03f, 0.44f, 0.03f}, a));
  }
}

}  // namespace

Mesh& Parts::operator[](int material) {
  for (auto& [id, mesh] : parts_) {
    if (id == material) return mesh;
  }
  return parts_.emplace_back(material, Mesh{}).second;
}

double unit_hash(uint64_t index, uint64_t salt) {
  uint64_t z = index * 0x9E3779B97F4A7C15ull + salt * 0xD1B54A32D192ED03ull + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

Parts storage_tank(const PlantMaterials& m, float radius, float height, bool dome_roof) {
  Parts parts;
  parts[m.concrete].append(cylinder(radius + 0.6f, 0.4f, 96, false, true));
  parts[m.tank_white].append(cylinder(radius, height, 128, false, false), at(0, 0, 0.4f));
  parts[m.tank_white].append(annulus(radius, radius + 0.7f, 128), at(0, 0, 0.4f + 0.8f * height));  // wind girder
  const float rise = dome_roof ? 0.15f * radius : 0.1f * radius;
  parts[m.roof_grey].append(dome_roof ? dome(radius, rise, 128, 8) : cone(radius, rise, 128), at(0, 0, 0.4f + height));
  ring_rail(parts[m.steel_yellow], radius - 0.3f, 0.4f + height, 128);
  // Spiral stair: 0.2 m risers climbing a third of a turn round the shell.
  const int steps = static_cast<int>(height / 0.2f);
  for (int i = 0; i < steps; ++i) {
    const float a = 2.0f * kPi / 3.0f * static_cast<float>(i) / static_cast<float>(steps);
    const V centre((radius + 0.55f) * std::cos(a), (radius + 0.55f) * std::sin(a),
                   0.4f + 0.2f * static_cast<float>(i + 1));
    parts[m.steel_galvanized].append(box_at(centre, {0.9f, 0.28f, 0.05f}, a));
  }
  parts[m.steel_galvanized].append(tube({radius + 1.0f, 0, 0.8f}, {radius + 4.0f, 0, 0.8f}, 0.3f, 24));  // outlet
  return parts;
}

Parts column_tower(const PlantMaterials& m, float radius, float height) {
  Parts parts;
  parts[m.concrete].append(box_at({0, 0, 0.5f}, {2.4f * radius + 1.0f, 2.4f * radius + 1.0f, 1.0f}));
  parts[m.steel_red].append(cylinder(radius * 1.05f, 4.0f, 48, false, false), at(0, 0, 1.0f));  // skirt
  parts[m.pipe_aluminium].append(cylinder(radius, height - 5.0f, 64, false, false), at(0, 0, 5.0f));
  parts[m.pipe_aluminium].append(dome(radius, radius * 0.5f, 64, 6), at(0, 0, height));
  for (float z = 8.0f; z < height - 1.0f; z += 7.0f) {
    parts[m.grating].append(annulus(radius, radius + 1.3f, 48), at(0, 0, z));
    ring_rail(parts[m.steel_yellow], radius + 1.25f, z, 48);
    for (int k = 0; k < 3; ++k) {  // nozzles
      const float a = 2.0f * kPi * (static_cast<float>(k) / 3.0f + 0.1f);
      const V dir(std::cos(a), std::sin(a), 0.0f);
      parts[m.steel_galvanized].append(
          tube((radius - 0.1f) * dir + V(0, 0, z + 0.8f), (radius + 0.9f) * dir + V(0, 0, z + 0.8f), 0.15f, 16));
    }
  }
  ladder(parts[m.steel_yellow], radius + 1.3f, 0.0f, 1.0f, height - 1.0f);
  // Overhead vapour line down the side to the ground.
  const V line(-(radius + 0.9f), 0.0f, 0.0f);
  parts[m.pipe_aluminium].append(tube(line + V(0, 0, 1.0f), line + V(0, 0, height + 0.3f * radius), 0.3f, 24));
  return parts;
}

Parts spherical_tank(const PlantMaterials& m, float radius) {
  Parts parts;
  const float centre = radius + 2.5f;
  parts[m.tank_white].append(sphere(radius, 96, 48), at(0, 0, centre));
  for (int i = 0; i < 10; ++i) {
    const float a = 2.0f * kPi * static_cast<float>(i) / 10.0f;
    const V foot(radius * std::cos(a), radius * std::sin(a), 0.0f);
    parts[m.steel_galvanized].append(tube(foot, foot + V(0, 0, centre), 0.35f, 16));
    const float b = 2.0f * kPi * static_cast<float>(i + 1) / 10.0f;
    const V next(radius * std::cos(b), radius * std::sin(b), 0.0f);
    parts[m.steel_galvanized].append(tube(foot + V(0, 0, 0.5f), next + V(0, 0, centre - 1.0f), 0.08f, 8));
    parts[m.concrete].append(box_at(foot + V(0, 0, 0.3f), {1.2f, 1.2f, 0.6f}));
  }
  parts[m.grating].append(annulus(0.01f, 2.0f, 32), at(0, 0, centre + radius + 0.05f));
  ring_rail(parts[m.steel_yellow], 2.0f, centre + radius, 32);
  ladder(parts[m.steel_yellow], radius, kPi / 4.0f, 0.0f, centre);
  return parts;
}

Parts horizontal_drum(const PlantMaterials& m, float radius, float length) {
  Parts parts;
  const float axis = radius + 1.2f;
  parts[m.tank_grey].append(capsule_x(radius, length, 48, 8), at(0, 0, axis));
  for (const float x : {-0.3f * length, 0.3f * length}) {
    parts[m.concrete].append(box_at({x, 0, 0.6f}, {0.6f, 1.6f * radius, 1.2f}));
    parts[m.steel_galvanized].append(box_at({x, 0, 1.2f + 0.15f * radius}, {0.3f, 1.8f * radius, 0.3f * radius}));
  }
  for (int k = 0; k < 3; ++k) {
    const float x = (static_cast<float>(k) - 1.0f) * 0.35f * length;
    parts[m.steel_galvanized].append(tube({x, 0, axis + radius - 0.1f}, {x, 0, axis + radius + 0.6f}, 0.12f, 16));
  }
  return parts;
}

Parts flare_stack(const PlantMaterials& m, float height) {
  Parts parts;
  parts[m.concrete].append(box_at({0, 0, 0.5f}, {3.0f, 3.0f, 1.0f}));
  parts[m.steel_red].append(cylinder(0.6f, height - 3.0f, 24, false, false), at(0, 0, 1.0f));
  parts[m.steel_galvanized].append(cylinder(0.9f, 2.0f, 24, false, true), at(0, 0, height - 2.0f));
  parts[m.grating].append(annulus(0.6f, 1.8f, 24), at(0, 0, height - 4.0f));
  ring_rail(parts[m.steel_yellow], 1.75f, height - 4.0f, 24);
  ladder(parts[m.steel_yellow], 0.6f, 0.0f, 1.0f, height - 4.0f);
  for (int i = 0; i < 3; ++i) {  // guy wires to anchors 20 m out
    const float a = 2.0f * kPi * static_cast<float>(i) / 3.0f + 1.2f;
    const V anchor(20.0f * std::cos(a), 20.0f * std::sin(a), 0.0f);
    parts[m.steel_galvanized].append(tube(anchor, {0, 0, 0.7f * height}, 0.03f, 6));
    parts[m.concrete].append(box_at(anchor + V(0, 0, 0.25f), {1.0f, 1.0f, 0.5f}));
  }
  return parts;
}

Parts sign(const PlantMaterials& m) {
  Parts parts;
  parts[m.sign_post].append(tube({0, 0, 0}, {0, 0, 2.6f}, 0.04f, 8));
  parts[m.sign_retro].append(box_at({0, -0.06f, 2.2f}, {0.9f, 0.03f, 0.6f}));  // faces -y
  return parts;
}

Parts light_pole(const PlantMaterials& m) {
  Parts parts;
  parts[m.steel_galvanized].append(tube({0, 0, 0}, {0, 0, 9.0f}, 0.09f, 10));
  parts[m.steel_galvanized].append(box_at({0.7f, 0, 9.0f}, {1.4f, 0.08f, 0.08f}));
  parts[m.steel_galvanized].append(box_at({1.3f, 0, 8.9f}, {0.6f, 0.3f, 0.15f}));
  return parts;
}

}  // namespace lidartwin::scenegen
