#pragma once
// Hand-written glTF 2.0 documents for scene tests, built byte by byte here (independently of
// tinygltf and of the loader under test) so that index types, strides, embedded / external
// buffers, .glb containers and broken files can be made on purpose. Coordinates are glTF's (Y up).
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace lidartwin::test {

class GltfBuilder {
 public:
  // Float VEC3 positions; stride > 12 interleaves zero bytes after each vertex. Returns the accessor.
  int add_positions(const std::vector<float>& xyz, uint32_t stride = 12) {
    const size_t count = xyz.size() / 3;
    const size_t offset = begin_view();
    for (size_t i = 0; i < count; ++i) {
      append(&xyz[3 * i], 12);
      bin_.resize(bin_.size() + (stride - 12), 0);
    }
    nlohmann::json view{{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bin_.size() - offset}};
    if (stride != 12) view["byteStride"] = stride;
    return add_accessor(view, 5126, count, "VEC3");
  }

  // Indices of the C++ type's width: uint8_t → 5121, uint16_t → 5123, uint32_t → 5125.
  template <class T>
  int add_indices(const std::vector<T>& indices) {
    const size_t offset = begin_view();
    append(indices.data(), indices.size() * sizeof(T));
    const int type = sizeof(T) == 1 ? 5121 : sizeof(T) == 2 ? 5123 : 5125;
    return add_accessor({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bin_.size() - offset}}, type,
                        indices.size(), "SCALAR");
  }

  int add_material(nlohmann::json material) { return push(doc_["materials"], std::move(material)); }
  int add_mesh(const std::string& name, nlohmann::json primitives) {
    return push(doc_["meshes"], {{"name", name}, {"primitives", std::move(primitives)}});
  }
  int add_node(nlohmann::json node) { return push(doc_["nodes"], std::move(node)); }
  void set_roots(const std::vector<int>& roots) {
    doc_["scenes"] = {{{"nodes", roots}}};
    doc_["scene"] = 0;
  }

  nlohmann::json document(const std::string& buffer_uri) const {
    nlohmann::json doc = doc_;
    doc["asset"] = {{"version", "2.0"}};
    doc["buffers"] = {{{"byteLength", bin_.size()}}};
    if (!buffer_uri.empty()) doc["buffers"][0]["uri"] = buffer_uri;
    return doc;
  }

  void write_embedded(const std::filesystem::path& path) const {
    std::ofstream(path) << document("data:application/octet-stream;base64," + base64(bin_)).dump(1);
  }
  void write_external(const std::filesystem::path& path, const std::string& bin_name) const {
    std::ofstream(path.parent_path() / bin_name, std::ios::binary)
        .write(reinterpret_cast<const char*>(bin_.data()), static_cast<std::streamsize>(bin_.size()));
    std::ofstream(path) << document(bin_name).dump(1);
  }
  // glTF 2.0 spec 4.4 "GLB file format": 12-byte header, JSON chunk (space padded), BIN chunk.
  void write_glb(const std::filesystem::path& path) const {
    std::string json = document("").dump();
    json.resize((json.size() + 3) / 4 * 4, ' ');
    std::vector<uint8_t> bin = bin_;
    bin.resize((bin.size() + 3) / 4 * 4, 0);
    const auto u32 = [](size_t v) { return static_cast<uint32_t>(v); };
    std::vector<uint32_t> header{0x46546C67u, 2u, u32(12 + 8 + json.size() + 8 + bin.size()), u32(json.size()),
                                 0x4E4F534Au};
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(header.data()), 20)
        .write(json.data(), static_cast<std::streamsize>(json.size()));
    const std::vector<uint32_t> bin_header{u32(bin.size()), 0x004E4942u};
    out.write(reinterpret_cast<const char*>(bin_header.data()), 8);
    out.write(reinterpret_cast<const char*>(bin.data()), static_cast<std::streamsize>(bin.size()));
  }

  static std::string base64(const std::vector<uint8_t>& bytes) {
    static const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < bytes.size(); i += 3) {
      const size_t left = bytes.size() - i;
      uint32_t n = uint32_t{bytes[i]} << 16;
      if (left > 1) n |= uint32_t{bytes[i + 1]} << 8;
      if (left > 2) n |= uint32_t{bytes[i + 2]};
      out += alphabet[(n >> 18) & 63];
      out += alphabet[(n >> 12) & 63];
      out += left > 1 ? alphabet[(n >> 6) & 63] : '=';
      out += left > 2 ? alphabet[n & 63] : '=';
    }
    return out;
  }

 private:
  size_t begin_view() {
    bin_.resize((bin_.size() + 3) / 4 * 4, 0);  // keep every view 4-byte aligned (spec 3.6.2.4)
    return bin_.size();
  }
  void append(const void* data, size_t size) {
    const auto* bytes = static_cast<const uint8_t*>(data);
    bin_.insert(bin_.end(), bytes, bytes + size);
  }
  int add_accessor(nlohmann::json view, int component_type, size_t count, const char* type) {
    const int view_index = push(doc_["bufferViews"], std::move(view));
    return push(doc_["accessors"],
                {{"bufferView", view_index}, {"componentType", component_type}, {"count", count}, {"type", type}});
  }
  static int push(nlohmann::json& array, nlohmann::json value) {
    if (array.is_null()) array = nlohmann::json::array();
    array.push_back(std::move(value));
    return static_cast<int>(array.size() - 1);
  }

  nlohmann::json doc_ = nlohmann::json::object();
  std::vector<uint8_t> bin_;
};

}  // namespace lidartwin::test
