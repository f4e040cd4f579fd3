#pragma once
// A glTF 2.0 scene in Embree. glTF is metres with +Y up; the world frame used everywhere else is
// Z up: world = (x, -z, y). That conversion lives here and nowhere else (DESIGN.md).
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

struct RTCSceneTy;
struct RTCDeviceTy;

namespace lidartwin {

// The conversion itself, for tools that write glTF from world-frame geometry (tools/scenegen):
// world_point = world_from_gltf() * gltf_point.
Eigen::Matrix3d world_from_gltf();

// Surface optics at 865 nm. From glTF materials: extras.reflectivity (0..1, diffuse), else the
// luminance of baseColorFactor; extras.retroreflective (bool); extras.specular (0..1).
struct Material {
  std::string name;
  float reflectivity = 0.5f;
  bool retroreflective = false;
  float specular = 0.0f;
};

// The first surface along one ray (Scene::first_hit).
struct SceneHit {
  float distance;          // along the ray, in units of |direction| (metres for a unit direction)
  unsigned geom_id;        // Embree geometry: material(geom_id) is its material
  unsigned prim_id;        // triangle within it
  Eigen::Vector3f normal;  // Embree's geometric normal, world frame, not normalized
};

// Triangle j's plane as the caster measures a hit on it (column_caster.cpp, measure_hits): its
// first corner, and the cross product of its edges from that corner in double, as
// (v1 - v0) x (v2 - v0). Made once when the scene loads: read per hit, the corner's three vertices
// behind an index were two dependent cache misses.
struct TrianglePlane {
  double normal[3];
  float corner[3];
};

// One geometry's triangles as Embree intersects them, world frame: vertex i is
// vertices[3i .. 3i+2], triangle j joins vertices indices[3j .. 3j+2], its plane planes[j]. Valid
// while the Scene lives.
struct TriangleMesh {
  const float* vertices = nullptr;
  const uint32_t* indices = nullptr;
  const TrianglePlane* planes = nullptr;
};

class Scene {
 public:
  // Throws InputError naming the file and the problem (unreadable, not glTF, no triangles…).
  static Scene load(const std::filesystem::path& path);
  ~Scene();
  Scene(Scene&&) noexcept;
  Scene& operator=(Scene&&) noexcept;
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  RTCSceneTy* embree_scene() const;  // committed, for the caster's rtcIntersect calls
  // Material of an Embree hit (geomID); every geometry has one.
  const Material& material(unsigned geom_id) const;
  // One ray with rtcIntersect1, for tools and tests (the emulator casts 16-ray packets in
  // `caster`): the first surface with near_m <= distance <= far_m, or nothing.
  std::optional<SceneHit> first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                    float near_m = 0.0f, float far_m = std::numeric_limits<float>::infinity()) const;
  TriangleMesh mesh(unsigned geom_id) const;
  size_t triangle_count() const;
  size_t geometry_count() const;       // one Embree geometry per placed glTF primitive
  Eigen::AlignedBox3d bounds() const;  // world frame

 private:
  struct Impl;
  explicit Scene(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
