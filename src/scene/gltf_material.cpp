// Surface optics from glTF materials. glTF has no lidar channel, so the 865 nm diffuse reflectance
// comes from `extras.reflectivity` when the author gives it; otherwise the visible base colour's
// luminance is the best available guess (lidar-physics.md 2.2 uses ρ, the diffuse reflectance).
#include "scene/gltf_material.h"

#include <tiny_gltf.h>

#include "lidartwin/error.h"

namespace lidartwin::scene_detail {
namespace {

float unit_number(const tinygltf::Value& value, const std::string& key, const std::string& where) {
  const tinygltf::Value& v = value.Get(key);
  const double number = v.IsNumber() ? v.GetNumberAsDouble() : -1.0;
  if (!(number >= 0.0 && number <= 1.0)) {
    throw InputError(where + ": extras." + key + " must be a number in [0, 1]");
  }
  return static_cast<float>(number);
}

// Relative luminance of linear RGB (ITU-R BT.709 primaries; glTF baseColorFactor is linear).
float luminance(const std::vector<double>& rgba) {
  if (rgba.size() < 3) return 1.0f;  // glTF default base colour is white
  return static_cast<float>(0.2126 * rgba[0] + 0.7152 * rgba[1] + 0.0722 * rgba[2]);
}

}  // namespace

Material material_from_gltf(const tinygltf::Material& material, const std::string& where) {
  Material out;
  out.name = material.name;
  const tinygltf::Value& extras = material.extras;
  const bool has_extras = extras.IsObject();
  out.reflectivity = has_extras && extras.Has("reflectivity")
                         ? unit_number(extras, "reflectivity", where)
                         : luminance(material.pbrMetallicRoughness.baseColorFactor);
  if (has_extras && extras.Has("retroreflective")) {
    const tinygltf::Value& retro = extras.Get("retroreflective");
    if (!retro.IsBool()) throw InputError(where + ": extras.retroreflective must be true or false");
    out.retroreflective = retro.Get<bool>();
  }
  if (has_extras && extras.Has("specular")) out.specular = unit_number(extras, "specular", where);
  return out;
}

Material default_material() {
  Material out;
  out.name = "(default)";
  return out;
}

}  // namespace lidartwin::scene_detail
