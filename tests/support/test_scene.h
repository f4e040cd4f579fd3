#pragma once
// Writes small glTF 2.0 binary (.glb) scenes for tests: boxes and quads given in the Z-up world
// frame (scene/scene.h), stored in glTF's Y-up frame, one mesh and material per object.
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace lidartwin::test {

struct TestObject {
  std::string name;
  std::vector<Eigen::Vector3f> vertices;  // world frame, Z up, metres
  std::vector<uint32_t> indices;          // triangles
  float reflectivity = 0.5f;
  bool retroreflective = false;
};

// An axis-aligned box, faces outward.
inline TestObject box(std::string name, Eigen::Vector3f lo, Eigen::Vector3f hi, float reflectivity = 0.5f) {
  TestObject o{std::move(name), {}, {}, reflectivity, false};
  for (int i = 0; i < 8; ++i) {
    o.vertices.emplace_back((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(), (i & 4) ? hi.z() : lo.z());
  }
  o.indices = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
               2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  return o;
}

// A planar quad a-b-c-d (two triangles).
inline TestObject quad(std::string name, Eigen::Vector3f a, Eigen::Vector3f b, Eigen::Vector3f c, Eigen::Vector3f d,
                       float reflectivity = 0.5f) {
  return TestObject{std::move(name), {a, b, c, d}, {0, 1, 2, 0, 2, 3}, reflectivity, false};
}

namespace detail {
inline void append_bytes(std::vector<uint8_t>& bin, const void* data, size_t size) {
  const auto* p = static_cast<const uint8_t*>(data);
  bin.insert(bin.end(), p, p + size);
  while (bin.size() % 4 != 0) bin.push_back(0);
}
inline nlohmann::json add_object(const TestObject& o, size_t index, std::vector<uint8_t>& bin, nlohmann::json& doc) {
  std::vector<float> positions;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = Eigen::Vector3f::Constant(-1e30f);
  for (const auto& v : o.vertices) {
    const Eigen::Vector3f g(v.x(), v.z(), -v.y());  // world (x, y, z) = glTF (x, -z, y)
    positions.insert(positions.end(), {g.x(), g.y(), g.z()});
    lo = lo.cwiseMin(g);
    hi = hi.cwiseMax(g);
  }
  const size_t pos_offset = bin.size();
  append_bytes(bin, positions.data(), positions.size() * sizeof(float));
  const size_t idx_offset = bin.size();
  append_bytes(bin, o.indices.data(), o.indices.size() * sizeof(uint32_t));
  const size_t view = doc["bufferViews"].size();
  doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", pos_offset}, {"byteLength", positions.size() * 4}});
  doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", idx_offset}, {"byteLength", o.indices.size() * 4}});
  const size_t accessor = doc["accessors"].size();
  doc["accessors"].push_back({{"bufferView", view},
                              {"componentType", 5126},
                              {"count", o.vertices.size()},
                              {"type", "VEC3"},
                              {"min", {lo.x(), lo.y(), lo.z()}},
                              {"max", {hi.x(), hi.y(), hi.z()}}});
  doc["accessors"].push_back(
      {{"bufferView", view + 1}, {"componentType", 5125}, {"count", o.indices.size()}, {"type", "SCALAR"}});
  doc["materials"].push_back({{"name", o.name},
                              {"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1.0}}}},
                              {"extras", {{"reflectivity", o.reflectivity}, {"retroreflective", o.retroreflective}}}});
  doc["meshes"].push_back(
      {{"name", o.name},
       {"primitives", {{{"attributes", {{"POSITION", accessor}}}, {"indices", accessor + 1}, {"material", index}}}}});
  return {{"name", o.name}, {"mesh", index}};
}
}  // namespace detail

inline void write_glb(const std::filesystem::path& path, const std::vector<TestObject>& objects) {
  nlohmann::json doc = {{"asset", {{"version", "2.0"}}},          {"scene", 0},
                        {"bufferViews", nlohmann::json::array()}, {"accessors", nlohmann::json::array()},
                        {"materials", nlohmann::json::array()},   {"meshes", nlohmann::json::array()},
                        {"nodes", nlohmann::json::array()}};
  std::vector<uint8_t> bin;
  nlohmann::json node_ids = nlohmann::json::array();
  for (size_t i = 0; i < objects.size(); ++i) {
    doc["nodes"].push_back(detail::add_object(objects[i], i, bin, doc));
    node_ids.push_back(i);
  }
  doc["scenes"] = {{{"nodes", node_ids}}};
  doc["buffers"] = {{{"byteLength", bin.size()}}};
  std::string json = doc.dump();
  while (json.size() % 4 != 0) json.push_back(' ');
  const uint32_t total = static_cast<uint32_t>(12 + 8 + json.size() + 8 + bin.size());
  const uint32_t header[5] = {0x46546C67u, 2u, total, static_cast<uint32_t>(json.size()), 0x4E4F534Au};
  const uint32_t bin_header[2] = {static_cast<uint32_t>(bin.size()), 0x004E4942u};
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(header), sizeof header);
  out.write(json.data(), static_cast<std::streamsize>(json.size()));
  out.write(reinterpret_cast<const char*>(bin_header), sizeof bin_header);
  out.write(reinterpret_cast<const char*>(bin.data()), static_cast<std::streamsize>(bin.size()));
}

}  // namespace lidartwin::test
