#pragma once
// Triangle meshes for the scene generators, built in the world frame (Z up, metres). Every shape
// is closed or single-sided as noted; winding is counter-clockwise seen from outside.
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

namespace lidartwin::scenegen {

struct Mesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<uint32_t> indices;  // 3 per triangle

  size_t triangle_count() const { return indices.size() / 3; }
  void add_triangle(uint32_t a, uint32_t b, uint32_t c) { indices.insert(indices.end(), {a, b, c}); }
  // Appends `other` moved by `transform`.
  void append(const Mesh& other, const Eigen::Affine3f& transform = Eigen::Affine3f::Identity());
};

// Axis-aligned box between two corners (12 triangles).
Mesh box(const Eigen::Vector3f& lower, const Eigen::Vector3f& upper);
// Box of `size` centred at `centre`, turned by `yaw` (radians) about z.
Mesh box_at(const Eigen::Vector3f& centre, const Eigen::Vector3f& size, float yaw = 0.0f);
// Quad through four corners in order (2 triangles, facing by the right-hand rule).
Mesh quad(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, const Eigen::Vector3f& d);
// Vertical cylinder, base centre at the origin, axis +z.
Mesh cylinder(float radius, float height, int segments, bool bottom_cap, bool top_cap);
// Cone roof: base circle at z = 0, apex at z = height.
Mesh cone(float radius, float height, int segments);
// Spherical cap ("dome" roof) of base radius `radius` rising `height`, base at z = 0.
Mesh dome(float radius, float height, int segments, int rings);
// Full sphere centred at the origin.
Mesh sphere(float radius, int segments, int rings);
// Flat ring between two radii at z = 0, facing up (platforms, tank bottoms).
Mesh annulus(float inner, float outer, int segments);
// Ring-shaped tube (handrails): ring radius, tube radius, around z at height 0.
Mesh torus(float ring_radius, float tube_radius, int segments, int sides);
// Open tube from a to b (pipes).
Mesh tube(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float radius, int segments);
// Horizontal vessel along x, centred at the origin: cylinder with hemispherical heads.
Mesh capsule_x(float radius, float length, int segments, int rings);

}  // namespace lidartwin::scenegen
