// GlbWriter: meshes → tinygltf::Model → .glb (glTF 2.0 spec 3.6 buffers and 4.4 GLB).
#include "glb_writer.h"

#include <cmath>
#include <stdexcept>

#include <tiny_gltf.h>

#include "lidartwin/scene/scene.h"

namespace lidartwin::scenegen {
namespace {

// Appends bytes to buffer 0 (4-byte aligned, spec 3.6.2.4) and returns the new bufferView.
int add_view(tinygltf::Model& model, const void* data, size_t size, int target) {
  std::vector<unsigned char>& buffer = model.buffers[0].data;
  buffer.resize((buffer.size() + 3) / 4 * 4, 0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = buffer.size();
  view.byteLength = size;
  view.target = target;
  const auto* bytes = static_cast<const unsigned char*>(data);
  buffer.insert(buffer.end(), bytes, bytes + size);
  model.bufferViews.push_back(view);
  return static_cast<int>(model.bufferViews.size() - 1);
}

int add_accessor(tinygltf::Model& model, int view, int component_type, size_t count, int type) {
  tinygltf::Accessor accessor;
  accessor.bufferView = view;
  accessor.componentType = component_type;
  accessor.count = count;
  accessor.type = type;
  model.accessors.push_back(accessor);
  return static_cast<int>(model.accessors.size() - 1);
}

// Positions (with the min/max the spec requires for POSITION) and the smallest index type.
tinygltf::Primitive make_primitive(tinygltf::Model& model, const Mesh& mesh, int material) {
  Eigen::Vector3f lower = mesh.vertices.front(), upper = mesh.vertices.front();
  for (const auto& v : mesh.vertices) {
    lower = lower.cwiseMin(v);
    upper = upper.cwiseMax(v);
  }
  tinygltf::Primitive primitive;
  const int positions =
      add_accessor(model, add_view(model, mesh.vertices.data(), mesh.vertices.size() * sizeof(Eigen::Vector3f), 34962),
                   TINYGLTF_COMPONENT_TYPE_FLOAT, mesh.vertices.size(), TINYGLTF_TYPE_VEC3);
  model.accessors.back().minValues = {lower.x(), lower.y(), lower.z()};
  model.accessors.back().maxValues = {upper.x(), upper.y(), upper.z()};
  primitive.attributes["POSITION"] = positions;
  if (mesh.vertices.size() <= 65536) {
    const std::vector<uint16_t> small(mesh.indices.begin(), mesh.indices.end());
    primitive.indices = add_accessor(model, add_view(model, small.data(), small.size() * 2, 34963),
                                     TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, small.size(), TINYGLTF_TYPE_SCALAR);
  } else {
    primitive.indices = add_accessor(model, add_view(model, mesh.indices.data(), mesh.indices.size() * 4, 34963),
                                     TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, mesh.indices.size(), TINYGLTF_TYPE_SCALAR);
  }
  primitive.material = material;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  return primitive;
}

tinygltf::Material make_material(const MaterialSpec& spec) {
  tinygltf::Material material;
  material.name = spec.name;
  material.pbrMetallicRoughness.baseColorFactor = {spec.color[0], spec.color[1], spec.color[2], 1.0};
  material.pbrMetallicRoughness.metallicFactor = 0.0;
  material.pbrMetallicRoughness.roughnessFactor = 1.0 - 0.8 * spec.specular;
  tinygltf::Value::Object extras;
  extras["reflectivity"] = tinygltf::Value(spec.reflectivity);
  if (spec.retroreflective) extras["retroreflective"] = tinygltf::Value(true);
  if (spec.specular > 0.0) extras["specular"] = tinygltf::Value(spec.specular);
  material.extras = tinygltf::Value(extras);
  return material;
}

std::vector<double> quaternion(const Eigen::Quaterniond& q) { return {q.x(), q.y(), q.z(), q.w()}; }

}  // namespace

int GlbWriter::add_material(const MaterialSpec& material) {
  materials_.push_back(material);
  return static_cast<int>(materials_.size() - 1);
}

int GlbWriter::add_mesh(const std::string& name, const std::vector<std::pair<int, Mesh>>& parts) {
  std::vector<Part> kept;
  size_t triangles = 0;
  for (const auto& [material, mesh] : parts) {
    if (mesh.indices.empty()) continue;
    kept.push_back({material, mesh});
    triangles += mesh.triangle_count();
  }
  meshes_.emplace_back(name, std::move(kept));
  mesh_triangles_.push_back(triangles);
  return static_cast<int>(meshes_.size() - 1);
}

void GlbWriter::add_instance(int mesh, const std::string& name, const Eigen::Vector3d& translation, double yaw,
                             double scale) {
  instances_.push_back({mesh, name, translation, yaw, scale});
  triangles_ += mesh_triangles_.at(static_cast<size_t>(mesh));
}

void GlbWriter::write(const std::filesystem::path& path) const {
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "lidartwin-scenegen";
  model.buffers.resize(1);
  for (const auto& spec : materials_) model.materials.push_back(make_material(spec));
  for (const auto& [name, parts] : meshes_) {
    tinygltf::Mesh mesh;
    mesh.name = name;
    for (const auto& part : parts) mesh.primitives.push_back(make_primitive(model, part.mesh, part.material));
    model.meshes.push_back(mesh);
  }
  tinygltf::Node root;  // world (Z up) → glTF (Y up): the inverse of world_from_gltf()
  root.name = "z_up_world";
  root.rotation = quaternion(Eigen::Quaterniond(Eigen::Matrix3d(world_from_gltf().transpose())));
  for (const auto& instance : instances_) {
    tinygltf::Node node;
    node.name = instance.name;
    node.mesh = instance.mesh;
    node.translation = {instance.translation.x(), instance.translation.y(), instance.translation.z()};
    if (instance.yaw != 0.0)
      node.rotation = quaternion(Eigen::Quaterniond(Eigen::AngleAxisd(instance.yaw, Eigen::Vector3d::UnitZ())));
    if (instance.scale != 1.0) node.scale = {instance.scale, instance.scale, instance.scale};
    model.nodes.push_back(node);
    root.children.push_back(static_cast<int>(model.nodes.size() - 1));
  }
  model.nodes.push_back(root);
  model.scenes.push_back({});
  model.scenes[0].nodes = {static_cast<int>(model.nodes.size() - 1)};
  model.defaultScene = 0;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToFile(&model, path.string(), true, true, false, true)) {
    throw std::runtime_error(path.string() + ": cannot write glTF");
  }
}

}  // namespace lidartwin::scenegen
