// glTF file → triangle lists in the world frame: load with tinygltf, walk the default scene's node
// tree (glTF spec 3.5 "Nodes and hierarchy"), place every triangle primitive, then turn glTF's
// +Y-up frame into the world's Z-up frame. This file is the one place that conversion happens.
#include "scene/gltf_reader.h"

#include <fstream>

#include <tiny_gltf.h>

#include "lidartwin/error.h"
#include "scene/gltf_material.h"
#include "scene/gltf_primitive.h"

namespace lidartwin {

// world = (x, -z, y): a +90° rotation about x. glTF "up" (+Y) becomes world +Z, and glTF's
// front (+Z) becomes world -Y, so the frame stays right-handed.
Eigen::Matrix3d world_from_gltf() {
  Eigen::Matrix3d m;
  m << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  return m;
}

namespace scene_detail {
namespace {

namespace fs = std::filesystem;

// Images are irrelevant to a lidar; accept them undecoded (Debian's libtinygltf is built with
// stb_image, but our headers are compiled with TINYGLTF_NO_STB_IMAGE, so no default loader).
bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

bool is_glb(const fs::path& path) {
  char magic[4] = {};
  std::ifstream(path, std::ios::binary).read(magic, 4);
  return std::string_view(magic, 4) == "glTF";
}

tinygltf::Model load_model(const fs::path& path) {
  if (!fs::is_regular_file(path)) throw InputError(path.string() + ": no such file");
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&skip_image, nullptr);
  tinygltf::Model model;
  std::string error, warning;
  const bool ok = is_glb(path) ? loader.LoadBinaryFromFile(&model, &error, &warning, path.string())
                               : loader.LoadASCIIFromFile(&model, &error, &warning, path.string());
  if (!ok) {
    while (!error.empty() && error.back() == '\n') error.pop_back();
    throw InputError(path.string() + ": not a readable glTF 2.0 file: " + error);
  }
  return model;
}

// glTF 3.5.2: a node has either a column-major matrix or T·R·S.
Eigen::Matrix4d local_transform(const tinygltf::Node& node) {
  if (node.matrix.size() == 16) return Eigen::Map<const Eigen::Matrix4d>(node.matrix.data());
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  if (node.translation.size() == 3) t.translate(Eigen::Vector3d(node.translation.data()));
  if (node.rotation.size() == 4) {
    const auto& q = node.rotation;  // x, y, z, w
    t.rotate(Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized());
  }
  if (node.scale.size() == 3) t.scale(Eigen::Vector3d(node.scale.data()));
  return t.matrix();
}

class Flattener {
 public:
  Flattener(const tinygltf::Model& model, std::string file) : model_(model), file_(std::move(file)) {}

  void visit(int node_index, const Eigen::Matrix4d& world_from_parent, size_t depth) {
    if (node_index < 0 || static_cast<size_t>(node_index) >= model_.nodes.size()) {
      throw InputError(file_ + ": node #" + std::to_string(node_index) + " does not exist");
    }
    if (depth > model_.nodes.size()) throw InputError(file_ + ": the node hierarchy has a cycle");
    const tinygltf::Node& node = model_.nodes[static_cast<size_t>(node_index)];
    const Eigen::Matrix4d world_from_node = world_from_parent * local_transform(node);
    if (node.mesh >= 0) add_mesh(node.mesh, world_from_node);
    for (const int child : node.children) visit(child, world_from_node, depth + 1);
  }

  std::vector<MeshPart> parts;

 private:
  void add_mesh(int mesh_index, const Eigen::Matrix4d& world_from_mesh) {
    if (static_cast<size_t>(mesh_index) >= model_.meshes.size()) {
      throw InputError(file_ + ": mesh #" + std::to_string(mesh_index) + " does not exist");
    }
    const tinygltf::Mesh& mesh = model_.meshes[static_cast<size_t>(mesh_index)];
    for (size_t p = 0; p < mesh.primitives.size(); ++p) {
      const tinygltf::Primitive& primitive = mesh.primitives[p];
      if (!is_triangle_mode(primitive.mode)) continue;  // points and lines reflect nothing
      MeshPart part;
      part.label = "mesh '" + mesh.name + "' (#" + std::to_string(mesh_index) + ") primitive " + std::to_string(p);
      if (primitive.material >= static_cast<int>(model_.materials.size())) {
        throw InputError(file_ + ": " + part.label + ": material #" + std::to_string(primitive.material) +
                         " does not exist");
      }
      PrimitiveTriangles triangles = read_primitive(model_, primitive, file_ + ": " + part.label);
      part.vertices = place(triangles.positions, world_from_mesh);
      part.indices = std::move(triangles.indices);
      part.material = primitive.material;
      if (!part.indices.empty()) parts.push_back(std::move(part));
    }
  }

  static std::vector<float> place(const std::vector<float>& positions, const Eigen::Matrix4d& world_from_mesh) {
    std::vector<float> out(positions.size());
    for (size_t i = 0; i + 2 < positions.size(); i += 3) {
      const Eigen::Vector4d p(Eigen::Vector4f(positions[i], positions[i + 1], positions[i + 2], 1.0f).cast<double>());
      const Eigen::Vector4d w = world_from_mesh * p;
      for (size_t k = 0; k < 3; ++k) out[i + k] = static_cast<float>(w[static_cast<Eigen::Index>(k)]);
    }
    return out;
  }

  const tinygltf::Model& model_;
  std::string file_;
};

// The nodes to draw: the default scene's roots (glTF 3.5.1), else scene 0, else every parentless node.
std::vector<int> root_nodes(const tinygltf::Model& model) {
  if (!model.scenes.empty()) {
    const bool valid_default = model.defaultScene >= 0 && model.defaultScene < static_cast<int>(model.scenes.size());
    return model.scenes[valid_default ? static_cast<size_t>(model.defaultScene) : 0].nodes;
  }
  std::vector<bool> is_child(model.nodes.size(), false);
  for (const auto& node : model.nodes) {
    for (const int child : node.children) {
      if (child >= 0 && static_cast<size_t>(child) < is_child.size()) is_child[static_cast<size_t>(child)] = true;
    }
  }
  std::vector<int> roots;
  for (size_t i = 0; i < model.nodes.size(); ++i) {
    if (!is_child[i]) roots.push_back(static_cast<int>(i));
  }
  return roots;
}

}  // namespace

GltfContent read_gltf(const std::filesystem::path& path) {
  const tinygltf::Model model = load_model(path);
  const std::string file = path.string();
  GltfContent content;
  for (size_t i = 0; i < model.materials.size(); ++i) {
    const std::string where = file + ": material '" + model.materials[i].name + "' (#" + std::to_string(i) + ")";
    content.materials.push_back(material_from_gltf(model.materials[i], where));
  }
  Eigen::Matrix4d world_from_root = Eigen::Matrix4d::Identity();
  world_from_root.topLeftCorner<3, 3>() = world_from_gltf();
  Flattener flattener(model, file);
  for (const int root : root_nodes(model)) flattener.visit(root, world_from_root, 0);
  content.parts = std::move(flattener.parts);
  return content;
}

}  // namespace scene_detail
}  // namespace lidartwin
