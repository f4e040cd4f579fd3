#pragma once
// glTF material → Material (README "Scenes and materials").
#include <string>

#include "lidartwin/scene/scene.h"

namespace tinygltf {
struct Material;
}  // namespace tinygltf

namespace lidartwin::scene_detail {

// `where` ("file: material 'paint' (#3)") prefixes errors about bad extras.
Material material_from_gltf(const tinygltf::Material& material, const std::string& where);

// Used for primitives without a material.
Material default_material();

}  // namespace lidartwin::scene_detail
