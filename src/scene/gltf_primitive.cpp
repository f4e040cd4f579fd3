// Reading one glTF primitive's triangles (glTF 2.0 spec, 3.6 "Binary data storage" and 3.7.2
// "Meshes"): every read is bounds-checked against its buffer, so a broken file is an InputError,
// never an out-of-bounds read.
#include "scene/gltf_primitive.h"

#include <cstring>

#include <tiny_gltf.h>

#include "lidartwin/error.h"

namespace lidartwin::scene_detail {
namespace {

// The bytes of element i of an accessor: base pointer, stride and element size, checked once.
struct AccessorView {
  const unsigned char* base = nullptr;
  size_t stride = 0;
  size_t count = 0;
};

const tinygltf::Accessor& accessor_at(const tinygltf::Model& model, int index, const std::string& where) {
  if (index < 0 || static_cast<size_t>(index) >= model.accessors.size()) {
    throw InputError(where + ": accessor #" + std::to_string(index) + " does not exist");
  }
  return model.accessors[static_cast<size_t>(index)];
}

AccessorView view_of(const tinygltf::Model& model, int accessor_index, size_t element_size, const std::string& where) {
  const std::string name = "accessor #" + std::to_string(accessor_index);
  const tinygltf::Accessor& accessor = accessor_at(model, accessor_index, where);
  if (accessor.sparse.isSparse) throw InputError(where + ": " + name + " is sparse (not supported)");
  if (accessor.bufferView < 0 || static_cast<size_t>(accessor.bufferView) >= model.bufferViews.size()) {
    throw InputError(where + ": " + name + " has no valid bufferView");
  }
  const tinygltf::BufferView& view = model.bufferViews[static_cast<size_t>(accessor.bufferView)];
  if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= model.buffers.size()) {
    throw InputError(where + ": " + name + " refers to a missing buffer");
  }
  const std::vector<unsigned char>& data = model.buffers[static_cast<size_t>(view.buffer)].data;
  const size_t stride = view.byteStride != 0 ? view.byteStride : element_size;
  if (accessor.count > data.size())
    throw InputError(where + ": " + name + " has more elements than its buffer has bytes");
  const size_t start = view.byteOffset + accessor.byteOffset;
  const size_t end = accessor.count == 0 ? start : start + (accessor.count - 1) * stride + element_size;
  if (end > view.byteOffset + view.byteLength || end > data.size()) {
    throw InputError(where + ": " + name + " reads past the end of its bufferView or buffer");
  }
  return {data.data() + start, stride, accessor.count};
}

std::vector<float> read_positions(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                  const std::string& where) {
  const auto it = primitive.attributes.find("POSITION");
  if (it == primitive.attributes.end()) throw InputError(where + ": no POSITION attribute");
  const tinygltf::Accessor& accessor = accessor_at(model, it->second, where);
  if (accessor.type != TINYGLTF_TYPE_VEC3 || accessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
    throw InputError(where + ": POSITION must be a float VEC3 accessor");
  }
  const AccessorView view = view_of(model, it->second, 3 * sizeof(float), where);
  std::vector<float> positions(3 * view.count);
  for (size_t i = 0; i < view.count; ++i)
    std::memcpy(&positions[3 * i], view.base + i * view.stride, 3 * sizeof(float));
  return positions;
}

// Vertex indices as stored (or 0..n-1 for a non-indexed primitive), before mode expansion.
std::vector<uint32_t> read_indices(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                   size_t vertex_count, const std::string& where) {
  std::vector<uint32_t> indices;
  if (primitive.indices < 0) {
    indices.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) indices[i] = static_cast<uint32_t>(i);
    return indices;
  }
  const tinygltf::Accessor& accessor = accessor_at(model, primitive.indices, where);
  const int type = accessor.componentType;
  const size_t size = type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                      : type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                      : type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                       : 0;
  if (size == 0 || accessor.type != TINYGLTF_TYPE_SCALAR) {
    throw InputError(where + ": indices must be scalar unsigned byte, short or int");
  }
  const AccessorView view = view_of(model, primitive.indices, size, where);
  indices.resize(view.count);
  for (size_t i = 0; i < view.count; ++i) {
    uint32_t value = 0;  // little-endian (glTF 3.6.2.2), as is the host
    std::memcpy(&value, view.base + i * view.stride, size);
    if (value >= vertex_count) {
      throw InputError(where + ": index " + std::to_string(value) + " (element " + std::to_string(i) +
                       ") is out of range for " + std::to_string(vertex_count) + " vertices");
    }
    indices[i] = value;
  }
  return indices;
}

// Strips and fans as triangle lists, winding as in glTF spec 3.7.2.1.
std::vector<uint32_t> to_triangle_list(std::vector<uint32_t> v, int mode) {
  if (mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
    v.resize(v.size() - v.size() % 3);
    return v;
  }
  std::vector<uint32_t> list;
  for (size_t i = 0; i + 2 < v.size(); ++i) {
    if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      list.insert(list.end(), {v[i], v[i + 1 + i % 2], v[i + 2 - i % 2]});
    } else {
      list.insert(list.end(), {v[i + 1], v[i + 2], v[0]});
    }
  }
  return list;
}

}  // namespace

bool is_triangle_mode(int mode) {
  return mode == -1 || mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
         mode == TINYGLTF_MODE_TRIANGLE_FAN;
}

PrimitiveTriangles read_primitive(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                  const std::string& where) {
  PrimitiveTriangles out;
  out.positions = read_positions(model, primitive, where);
  out.indices = to_triangle_list(read_indices(model, primitive, out.positions.size() / 3, where), primitive.mode);
  return out;
}

}  // namespace lidartwin::scene_detail
