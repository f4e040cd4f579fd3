#pragma once
// Collects meshes, materials and placed instances, and writes them as one glTF 2.0 binary (.glb)
// through tinygltf. Geometry is given in the world frame (Z up); one root node turns it into
// glTF's Y-up frame with the inverse of scene/scene.h's world_from_gltf(), so Scene::load gives
// back exactly the world coordinates used here.
#include <array>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "mesh.h"

namespace lidartwin::scenegen {

// README "Scenes and materials": reflectivity is the 865 nm diffuse reflectance the lidar sees;
// colour is only for viewers.
struct MaterialSpec {
  std::string name;
  double reflectivity = 0.5;
  bool retroreflective = false;
  double specular = 0.0;
  std::array<double, 3> color{0.5, 0.5, 0.5};
};

class GlbWriter {
 public:
  int add_material(const MaterialSpec& material);
  // One glTF mesh with one primitive per (material, triangles) part; empty parts are dropped.
  int add_mesh(const std::string& name, const std::vector<std::pair<int, Mesh>>& parts);
  // Places a mesh: world_from_mesh = translation · yaw about z · uniform scale.
  void add_instance(int mesh, const std::string& name, const Eigen::Vector3d& translation, double yaw = 0.0,
                    double scale = 1.0);
  // Number of triangles Scene::load will build (instances counted each time).
  size_t triangle_count() const { return triangles_; }
  void write(const std::filesystem::path& path) const;

 private:
  struct Instance {
    int mesh;
    std::string name;
    Eigen::Vector3d translation;
    double yaw, scale;
  };
  struct Part {
    int material;
    Mesh mesh;
  };
  std::vector<MaterialSpec> materials_;
  std::vector<std::pair<std::string, std::vector<Part>>> meshes_;
  std::vector<Instance> instances_;
  std::vector<size_t> mesh_triangles_;
  size_t triangles_ = 0;
};

}  // namespace lidartwin::scenegen
