// Mesh primitives for the generators; see mesh.h.
#include "mesh.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace lidartwin::scenegen {
namespace {

constexpr float kTau = 2.0f * std::numbers::pi_v<float>;

uint32_t next_index(const Mesh& mesh) { return static_cast<uint32_t>(mesh.vertices.size()); }

float angle(int i, int segments) { return kTau * static_cast<float>(i) / static_cast<float>(segments); }

// A surface of revolution about z through profile points (r, z), bottom to top; a point with
// r = 0 closes the surface there.
Mesh revolve(const std::vector<Eigen::Vector2f>& profile, int segments) {
  Mesh mesh;
  for (const auto& p : profile) {
    for (int s = 0; s < segments; ++s) {
      const float a = angle(s, segments);
      mesh.vertices.emplace_back(p.x() * std::cos(a), p.x() * std::sin(a), p.y());
    }
  }
  const auto at = [segments](size_t ring, int s) {
    return static_cast<uint32_t>(ring * static_cast<size_t>(segments) + static_cast<size_t>(s % segments));
  };
  for (size_t ring = 0; ring + 1 < profile.size(); ++ring) {
    for (int s = 0; s < segments; ++s) {
      if (profile[ring].x() > 0.0f) mesh.add_triangle(at(ring, s), at(ring, s + 1), at(ring + 1, s + 1));
      if (profile[ring + 1].x() > 0.0f) mesh.add_triangle(at(ring, s), at(ring + 1, s + 1), at(ring + 1, s));
    }
  }
  return mesh;
}

// A flat disc at height z; up = true faces +z.
Mesh disc(float radius, float z, int segments, bool up) {
  Mesh mesh;
  mesh.vertices.emplace_back(0.0f, 0.0f, z);
  for (int s = 0; s < segments; ++s) {
    mesh.vertices.emplace_back(radius * std::cos(angle(s, segments)), radius * std::sin(angle(s, segments)), z);
  }
  for (int s = 0; s < segments; ++s) {
    const uint32_t a = 1 + static_cast<uint32_t>(s), b = 1 + static_cast<uint32_t>((s + 1) % segments);
    up ? mesh.add_triangle(0, a, b) : mesh.add_triangle(0, b, a);
  }
  return mesh;
}

}  // namespace

void Mesh::append(const Mesh& other, const Eigen::Affine3f& transform) {
  const uint32_t base = next_index(*this);
  for (const auto& v : other.vertices) vertices.push_back(transform * v);
  const bool mirrored = transform.linear().determinant() < 0.0f;
  for (size_t i = 0; i < other.indices.size(); i += 3) {
    const uint32_t a = base + other.indices[i], b = base + other.indices[i + 1], c = base + other.indices[i + 2];
    mirrored ? add_triangle(a, c, b) : add_triangle(a, b, c);
  }
}

Mesh box(const Eigen::Vector3f& lower, const Eigen::Vector3f& upper) {
  Mesh mesh;
  for (int i = 0; i < 8; ++i) {
    mesh.vertices.emplace_back((i & 1) ? upper.x() : lower.x(), (i & 2) ? upper.y() : lower.y(),
                               (i & 4) ? upper.z() : lower.z());
  }
  // Faces as corner quads (bit 0 = x, 1 = y, 2 = z), counter-clockwise from outside.
  const uint32_t faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) {
    mesh.add_triangle(f[0], f[1], f[2]);
    mesh.add_triangle(f[0], f[2], f[3]);
  }
  return mesh;
}

Mesh box_at(const Eigen::Vector3f& centre, const Eigen::Vector3f& size, float yaw) {
  Mesh mesh;
  mesh.append(box(-size / 2, size / 2),
              Eigen::Translation3f(centre) * Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()));
  return mesh;
}

Mesh quad(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c, const Eigen::Vector3f& d) {
  Mesh mesh;
  mesh.vertices = {a, b, c, d};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  return mesh;
}

Mesh cylinder(float radius, float height, int segments, bool bottom_cap, bool top_cap) {
  Mesh mesh = revolve({{radius, 0.0f}, {radius, height}}, segments);
  if (bottom_cap) mesh.append(disc(radius, 0.0f, segments, false));
  if (top_cap) mesh.append(disc(radius, height, segments, true));
  return mesh;
}

Mesh cone(float radius, float height, int segments) { return revolve({{radius, 0.0f}, {0.0f, height}}, segments); }

Mesh dome(float radius, float height, int segments, int rings) {
  // Sphere through the base circle and the top: R = (r² + h²) / 2h, centre at h − R.
  const float big = (radius * radius + height * height) / (2.0f * height);
  const float start = std::asin(std::clamp(radius / big, -1.0f, 1.0f));
  std::vector<Eigen::Vector2f> profile;
  for (int i = 0; i <= rings; ++i) {
    const float a = start * (1.0f - static_cast<float>(i) / static_cast<float>(rings));
    profile.emplace_back(big * std::sin(a), height - big + big * std::cos(a));
  }
  return revolve(profile, segments);
}

Mesh sphere(float radius, int segments, int rings) {
  std::vector<Eigen::Vector2f> profile;
  for (int i = 0; i <= rings; ++i) {
    const float a = std::numbers::pi_v<float> * (static_cast<float>(i) / static_cast<float>(rings) - 0.5f);
    profile.emplace_back(i == 0 || i == rings ? 0.0f : radius * std::cos(a), radius * std::sin(a));
  }
  return revolve(profile, segments);
}

Mesh annulus(float inner, float outer, int segments) {
  Mesh mesh = revolve({{outer, 0.0f}, {inner, 0.0f}}, segments);
  return mesh;
}

Mesh torus(float ring_radius, float tube_radius, int segments, int sides) {
  std::vector<Eigen::Vector2f> profile;
  for (int i = 0; i <= sides; ++i) {
    const float a = angle(i, sides);
    profile.emplace_back(ring_radius + tube_radius * std::cos(a), tube_radius * std::sin(a));
  }
  return revolve(profile, segments);
}

Mesh tube(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float radius, int segments) {
  const Eigen::Vector3f axis = b - a;
  Mesh mesh;
  mesh.append(
      cylinder(radius, axis.norm(), segments, false, false),
      Eigen::Translation3f(a) * Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), axis.normalized()));
  return mesh;
}

Mesh capsule_x(float radius, float length, int segments, int rings) {
  std::vector<Eigen::Vector2f> profile;  // along z first, turned onto x below
  const float half = length / 2.0f;
  for (int i = 0; i <= rings; ++i) {
    const float a = std::numbers::pi_v<float> / 2.0f * static_cast<float>(i) / static_cast<float>(rings);
    profile.emplace_back(i == rings ? 0.0f : radius * std::cos(a), -half - radius * std::sin(a));
  }
  std::reverse(profile.begin(), profile.end());
  for (int i = 0; i <= rings; ++i) {
    const float a = std::numbers::pi_v<float> / 2.0f * static_cast<float>(i) / static_cast<float>(rings);
    profile.emplace_back(i == rings ? 0.0f : radius * std::cos(a), half + radius * std::sin(a));
  }
  Mesh mesh;
  mesh.append(revolve(profile, segments), Eigen::Affine3f(Eigen::AngleAxisf(kTau / 4, Eigen::Vector3f::UnitY())));
  return mesh;
}

}  // namespace lidartwin::scenegen
