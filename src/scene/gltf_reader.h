#pragma once
// glTF → plain triangle lists in the world frame (Z up). Private to the scene module: Scene::load
// hands the result to Embree. tinygltf types stay inside the .cpp files.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "lidartwin/scene/scene.h"

namespace lidartwin::scene_detail {

// One glTF primitive placed by one node (a mesh used by two nodes gives two parts).
struct MeshPart {
  std::string label;              // "mesh 'tank' (#3) primitive 1", for messages
  std::vector<float> vertices;    // x y z per vertex, world frame, metres
  std::vector<uint32_t> indices;  // 3 per triangle, all < vertices.size() / 3
  int material = -1;              // index into GltfContent::materials; -1 = the default material
};

struct GltfContent {
  std::vector<MeshPart> parts;
  std::vector<Material> materials;  // one per glTF material, same order
};

// Throws InputError naming the file (and the mesh/primitive or material) on any problem.
GltfContent read_gltf(const std::filesystem::path& path);

}  // namespace lidartwin::scene_detail
