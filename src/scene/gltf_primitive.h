#pragma once
// Triangles of one glTF primitive: positions through accessors (any byteStride), indices of any
// unsigned type or none, TRIANGLES / TRIANGLE_STRIP / TRIANGLE_FAN turned into a triangle list.
#include <cstdint>
#include <string>
#include <vector>

namespace tinygltf {
class Model;
struct Primitive;
}  // namespace tinygltf

namespace lidartwin::scene_detail {

struct PrimitiveTriangles {
  std::vector<float> positions;   // x y z, in the primitive's own (glTF) frame
  std::vector<uint32_t> indices;  // triangle list
};

// True for the modes we ray cast (4, 5, 6; glTF's default is 4).
bool is_triangle_mode(int mode);

// `where` ("file: mesh 'x' (#2) primitive 0") prefixes every error message.
PrimitiveTriangles read_primitive(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                  const std::string& where);

}  // namespace lidartwin::scene_detail
