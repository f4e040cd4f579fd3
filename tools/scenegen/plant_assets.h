#pragma once
// Building blocks of the industrial plant (scenes/plant.glb), each in its own frame: origin at the
// centre of its footprint on the ground, z up. plant.cpp places them.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "mesh.h"

namespace lidartwin::scenegen {

// Material indices in the GlbWriter (plant.cpp defines their reflectivities).
struct PlantMaterials {
  int gravel, asphalt, concrete;
  int tank_white, tank_grey, roof_grey;
  int steel_galvanized, steel_yellow, steel_red, grating;
  int pipe_aluminium, pipe_black, pipe_green;
  int wall_sheet, roof_sheet, glass, door;
  int sign_retro, sign_post;
};

class GlbWriter;

// Triangles grouped by material, one glTF primitive each.
class Parts {
 public:
  Mesh& operator[](int material);
  const std::vector<std::pair<int, Mesh>>& list() const { return parts_; }

 private:
  std::vector<std::pair<int, Mesh>> parts_;
};

// Deterministic uniform number in [0, 1) from (index, salt) with splitmix64 (Steele, Lea and Flood
// 2014): the layout is identical on every platform and standard library.
double unit_hash(uint64_t index, uint64_t salt);

Parts storage_tank(const PlantMaterials& m, float radius, float height, bool dome_roof);
Parts column_tower(const PlantMaterials& m, float radius, float height);
Parts spherical_tank(const PlantMaterials& m, float radius);
Parts horizontal_drum(const PlantMaterials& m, float radius, float length);
Parts flare_stack(const PlantMaterials& m, float height);
Parts process_module(const PlantMaterials& m);
// Rack along +x from x = 0 to `length`, bents every 6 m, pipes on `levels` levels.
Parts pipe_rack(const PlantMaterials& m, float length, int levels, int pipes_per_level);
Parts building(const PlantMaterials& m, const Eigen::Vector3f& size);
// Fence around the rectangle |x| <= half.x, |y| <= half.y, with gaps where |x| or |y| < gate.
Parts fence(const PlantMaterials& m, const Eigen::Vector2f& half, float gate);
Parts sign(const PlantMaterials& m);
Parts light_pole(const PlantMaterials& m);

// The plant's materials, added to a scene (plant.cpp; the yard uses them too).
PlantMaterials add_plant_materials(GlbWriter& out);
// One mesh made of `parts`, placed at each (x, y, z, yaw).
void place(GlbWriter& out, const Parts& parts, const std::string& name, const std::vector<Eigen::Vector4d>& where);

}  // namespace lidartwin::scenegen
