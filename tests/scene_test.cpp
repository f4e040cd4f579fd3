// Scene: hand-made glTF files (written by tests/support/gltf_builder.h) are cast with rtcIntersect1
// at known geometry, so the glTF Y-up → world Z-up conversion, node transforms, index types,
// strides, strips/fans and container variants are checked against hand-computed hits.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "lidartwin/error.h"
#include "lidartwin/scene/scene.h"
#include "support/gltf_builder.h"
#include "support/scene_rays.h"

namespace lidartwin {
namespace {

using nlohmann::json;
using test::cast;
using test::GltfBuilder;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

// A square of side 2·half, centred at c (glTF frame), spanned by unit axes u and v.
std::vector<float> square(const Eigen::Vector3f& c, const Eigen::Vector3f& u, const Eigen::Vector3f& v,
                          float half = 1.0f) {
  std::vector<float> xyz;
  for (const auto& [a, b] : {std::pair{-1.0f, -1.0f}, {1.0f, -1.0f}, {1.0f, 1.0f}, {-1.0f, 1.0f}}) {
    const Eigen::Vector3f p = c + half * (a * u + b * v);
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  }
  return xyz;
}

const std::vector<uint16_t> kQuad{0, 1, 2, 0, 2, 3};

class SceneFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lidartwin_scene_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string error_loading(const fs::path& path) {
    try {
      Scene::load(path);
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no InputError for " << path;
    return {};
  }
  fs::path dir_;
};

// A wall 10 m in front along glTF -Z and a floor 2 m below along glTF -Y.
GltfBuilder wall_and_floor() {
  GltfBuilder b;
  const int wall_material = b.add_material({{"name", "grey wall"}, {"extras", {{"reflectivity", 0.2}}}});
  const int floor_material =
      b.add_material({{"name", "floor"}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1.0}}}}});
  const int wall = b.add_positions(square({0, 0, -10}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY()));
  const int floor = b.add_positions(square({0, -2, 0}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitZ(), 5.0f));
  const int indices = b.add_indices(kQuad);
  b.add_mesh("wall",
             json::array({{{"attributes", {{"POSITION", wall}}}, {"indices", indices}, {"material", wall_material}}}));
  b.add_mesh(
      "floor",
      json::array({{{"attributes", {{"POSITION", floor}}}, {"indices", indices}, {"material", floor_material}}}));
  b.add_node({{"mesh", 0}});
  b.add_node({{"mesh", 1}});
  b.set_roots({0, 1});
  return b;
}

void expect_wall_and_floor(const Scene& scene) {
  EXPECT_EQ(scene.triangle_count(), 4u);
  // glTF (x, y, z) → world (x, -z, y): the wall at glTF z = -10 is at world y = +10 ...
  const auto wall = cast(scene, {0, 0, 0}, {0, 1, 0});
  ASSERT_TRUE(wall);
  EXPECT_NEAR(wall->distance, 10.0f, 1e-5f);
  EXPECT_FLOAT_EQ(scene.material(wall->geom_id).reflectivity, 0.2f);
  EXPECT_GT(std::abs(wall->normal.normalized().y()), 0.999f);
  EXPECT_FALSE(cast(scene, {0, 0, 0}, {0, -1, 0}));
  // ... and the floor at glTF y = -2 is at world z = -2.
  const auto floor = cast(scene, {0, 0, 0}, {0, 0, -1});
  ASSERT_TRUE(floor);
  EXPECT_NEAR(floor->distance, 2.0f, 1e-5f);
  EXPECT_EQ(scene.material(floor->geom_id).name, "floor");
  EXPECT_FALSE(cast(scene, {0, 0, 0}, {0, 0, 1}));
  const Eigen::AlignedBox3d bounds = scene.bounds();
  EXPECT_NEAR(bounds.min().z(), -2.0, 1e-6);
  EXPECT_NEAR(bounds.max().y(), 10.0, 1e-6);
}

TEST_F(SceneFiles, EmbeddedBufferIsConvertedFromYUpToZUp) {
  wall_and_floor().write_embedded(dir_ / "embedded.gltf");
  expect_wall_and_floor(Scene::load(dir_ / "embedded.gltf"));
}

TEST_F(SceneFiles, ExternalBufferAndGlbGiveTheSameScene) {
  const GltfBuilder b = wall_and_floor();
  b.write_external(dir_ / "external.gltf", "external.bin");
  b.write_glb(dir_ / "binary.glb");
  expect_wall_and_floor(Scene::load(dir_ / "external.gltf"));
  expect_wall_and_floor(Scene::load(dir_ / "binary.glb"));
}

TEST_F(SceneFiles, NodeTransformsComposeParentToChild) {
  GltfBuilder b;
  const int unit = b.add_positions(square({0, 0, 0}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY(), 0.5f));
  b.add_mesh("unit", json::array({{{"attributes", {{"POSITION", unit}}}, {"indices", b.add_indices(kQuad)}}}));
  // Parent: up 3 m, turned +90° about glTF Y; child: 8 m along glTF -Z, scaled ×2.
  const double s = std::sqrt(0.5);
  b.add_node({{"translation", {0, 3, 0}}, {"rotation", {0, s, 0, s}}, {"children", {1}}});
  b.add_node({{"translation", {0, 0, -8}}, {"scale", {2, 2, 2}}, {"mesh", 0}});
  // A column-major matrix: stretch x by 4, move 10 m along x.
  b.add_node({{"matrix", {4, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 10, 0, 0, 1}}, {"mesh", 0}});
  b.set_roots({0, 2});
  b.write_embedded(dir_ / "nodes.gltf");
  const Scene scene = Scene::load(dir_ / "nodes.gltf");
  EXPECT_EQ(scene.geometry_count(), 2u);  // one mesh, placed twice
  // R_y(90°)·(0, 0, -8) + (0, 3, 0) = (-8, 3, 0) in glTF = world (-8, 0, 3); a 2 m square facing x.
  const auto hit = cast(scene, {0, 0, 3.9}, {-1, 0, 0});
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->distance, 8.0f, 1e-5f);
  EXPECT_FALSE(cast(scene, {0, 0, 4.1}, {-1, 0, 0}));
  // The matrix instance spans world x ∈ [8, 12] in the plane y = 0.
  ASSERT_TRUE(cast(scene, {11.9, -5, 0}, {0, 1, 0}));
  EXPECT_NEAR(cast(scene, {11.9, -5, 0}, {0, 1, 0})->distance, 5.0f, 1e-5f);
  EXPECT_FALSE(cast(scene, {12.1, -5, 0}, {0, 1, 0}));
}

TEST_F(SceneFiles, EveryIndexTypeStrideAndTriangleMode) {
  GltfBuilder b;
  json primitives = json::array();
  const auto at = [](int k) { return Eigen::Vector3f(3.0f * static_cast<float>(k), 0, 0); };
  const auto quad = [&](int k) { return square(at(k), Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY(), 0.5f); };
  primitives.push_back({{"attributes", {{"POSITION", b.add_positions(quad(0))}}},
                        {"indices", b.add_indices(std::vector<uint8_t>{0, 1, 2, 0, 2, 3})}});
  primitives.push_back({{"attributes", {{"POSITION", b.add_positions(quad(1))}}}, {"indices", b.add_indices(kQuad)}});
  primitives.push_back({{"attributes", {{"POSITION", b.add_positions(quad(2), 20)}}},
                        {"indices", b.add_indices(std::vector<uint32_t>{0, 1, 2, 0, 2, 3})}});
  const std::vector<float> corners = quad(3);
  std::vector<float> unrolled;  // non-indexed: the six corners of the two triangles
  for (const uint16_t i : kQuad) unrolled.insert(unrolled.end(), &corners[3 * i], &corners[3 * i] + 3);
  primitives.push_back({{"attributes", {{"POSITION", b.add_positions(unrolled)}}}, {"mode", 4}});
  std::vector<float> strip = quad(4);  // corners in strip order: 0, 1, 3, 2
  std::swap_ranges(strip.begin() + 6, strip.begin() + 9, strip.begin() + 9);
  primitives.push_back({{"attributes", {{"POSITION", b.add_positions(strip)}}}, {"mode", 5}});
  primitives.push_back({{"attributes", {{"POSITION", b.add_positions(quad(5))}}}, {"mode", 6}});
  b.add_mesh("variants", primitives);
  b.add_node({{"mesh", 0}});
  b.set_roots({0});
  b.write_embedded(dir_ / "variants.gltf");
  const Scene scene = Scene::load(dir_ / "variants.gltf");
  EXPECT_EQ(scene.geometry_count(), 6u);
  EXPECT_EQ(scene.triangle_count(), 12u);
  for (int k = 0; k < 6; ++k) {
    SCOPED_TRACE(k);
    // Both halves of each square: below and above its diagonal.
    for (const double side : {-0.25, 0.25}) {
      const auto hit = cast(scene, {3.0 * k - side, -5, side}, {0, 1, 0});
      ASSERT_TRUE(hit);
      EXPECT_EQ(hit->geom_id, static_cast<unsigned>(k));
      EXPECT_NEAR(hit->distance, 5.0f, 1e-5f);
    }
  }
}

TEST_F(SceneFiles, MaterialsFromExtrasOrBaseColor) {
  GltfBuilder b;
  b.add_material({{"name", "retro sign"}, {"extras", {{"reflectivity", 0.9}, {"retroreflective", true}}}});
  b.add_material({{"name", "paint"},
                  {"pbrMetallicRoughness", {{"baseColorFactor", {0.2, 0.4, 0.6, 1.0}}}},
                  {"extras", {{"specular", 0.3}}}});
  const int indices = b.add_indices(kQuad);
  json primitives = json::array();
  for (int k = 0; k < 3; ++k) {
    const auto xyz = square({3.0f * static_cast<float>(k), 0, 0}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY());
    json primitive{{"attributes", {{"POSITION", b.add_positions(xyz)}}}, {"indices", indices}};
    if (k < 2) primitive["material"] = k;  // the third has none
    primitives.push_back(primitive);
  }
  b.add_mesh("signs", primitives);
  b.add_node({{"mesh", 0}});
  b.set_roots({0});
  b.write_embedded(dir_ / "materials.gltf");
  const Scene scene = Scene::load(dir_ / "materials.gltf");
  const Material& retro = scene.material(cast(scene, {0, -5, 0.1}, {0, 1, 0}).value().geom_id);
  EXPECT_EQ(retro.name, "retro sign");
  EXPECT_FLOAT_EQ(retro.reflectivity, 0.9f);
  EXPECT_TRUE(retro.retroreflective);
  const Material& paint = scene.material(cast(scene, {3, -5, 0.1}, {0, 1, 0}).value().geom_id);
  EXPECT_NEAR(paint.reflectivity, 0.2126 * 0.2 + 0.7152 * 0.4 + 0.0722 * 0.6, 1e-6);  // BT.709 luminance
  EXPECT_FLOAT_EQ(paint.specular, 0.3f);
  EXPECT_FALSE(paint.retroreflective);
  const Material& none = scene.material(cast(scene, {6, -5, 0.1}, {0, 1, 0}).value().geom_id);
  EXPECT_EQ(none.name, "(default)");
  EXPECT_FLOAT_EQ(none.reflectivity, 0.5f);
}

TEST_F(SceneFiles, ErrorsNameTheFileAndTheCulprit) {
  EXPECT_EQ(error_loading(dir_ / "absent.glb"), (dir_ / "absent.glb").string() + ": no such file");
  std::ofstream(dir_ / "garbage.gltf") << "{ not json";
  EXPECT_THAT(error_loading(dir_ / "garbage.gltf"),
              HasSubstr((dir_ / "garbage.gltf").string() + ": not a readable glTF 2.0 file: "));

  GltfBuilder points;
  points.add_mesh(
      "dots", json::array({{{"attributes", {{"POSITION", points.add_positions({0, 0, 0, 1, 0, 0})}}}, {"mode", 0}}}));
  points.add_node({{"mesh", 0}});
  points.set_roots({0});
  points.write_embedded(dir_ / "points.gltf");
  EXPECT_THAT(error_loading(dir_ / "points.gltf"), HasSubstr("points.gltf: no triangles"));

  GltfBuilder broken;
  const int corners = broken.add_positions(square({0, 0, 0}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY()));
  broken.add_mesh("fine", json::array({{{"attributes", {{"POSITION", corners}}}}}));
  broken.add_mesh("broken", json::array({{{"attributes", {{"POSITION", corners}}}, {"indices", 0}},
                                         {{"attributes", {{"POSITION", corners}}},
                                          {"indices", broken.add_indices(std::vector<uint16_t>{0, 1, 7})}}}));
  broken.add_node({{"mesh", 1}});
  broken.set_roots({0});
  broken.write_embedded(dir_ / "broken.gltf");
  EXPECT_THAT(error_loading(dir_ / "broken.gltf"),
              HasSubstr("broken.gltf: mesh 'broken' (#1) primitive 0: indices must be scalar unsigned"));
}

TEST_F(SceneFiles, OutOfRangeIndexAndBadExtras) {
  GltfBuilder b;
  b.add_material({{"name", "shiny"}, {"extras", {{"reflectivity", 1.5}}}});
  const int corners = b.add_positions(square({0, 0, 0}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY()));
  b.add_mesh("quad", json::array({{{"attributes", {{"POSITION", corners}}},
                                   {"indices", b.add_indices(std::vector<uint16_t>{0, 1, 2, 0, 2, 7})}}}));
  b.add_node({{"mesh", 0}});
  b.set_roots({0});
  b.write_embedded(dir_ / "index.gltf");
  EXPECT_THAT(error_loading(dir_ / "index.gltf"),
              HasSubstr("index.gltf: material 'shiny' (#0): extras.reflectivity must be a number in [0, 1]"));
  json doc = json::parse(std::ifstream(dir_ / "index.gltf"));
  doc["materials"][0]["extras"]["reflectivity"] = 0.5;
  std::ofstream(dir_ / "index.gltf") << doc.dump();
  EXPECT_THAT(
      error_loading(dir_ / "index.gltf"),
      HasSubstr("index.gltf: mesh 'quad' (#0) primitive 0: index 7 (element 5) is out of range for 4 vertices"));
  doc["accessors"][0]["count"] = 400;  // positions now run past their buffer
  std::ofstream(dir_ / "index.gltf") << doc.dump();
  EXPECT_THAT(error_loading(dir_ / "index.gltf"), HasSubstr("index.gltf: mesh 'quad' (#0) primitive 0: "));
}

// The committed scenes (tools/scenegen), checked from the files alone.
const fs::path kScenes = fs::path(LIDARTWIN_SOURCE_DIR) / "scenes";

struct TumRow {
  double time_s;
  Eigen::Vector3d position;
  Eigen::Quaterniond rotation;
};

std::vector<TumRow> read_tum(const fs::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  std::vector<TumRow> rows;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double t, x, y, z, qx, qy, qz, qw;
    fields >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
    rows.push_back({t, {x, y, z}, Eigen::Quaterniond(qw, qx, qy, qz)});
  }
  return rows;
}

TEST(ShippedScenes, PlantIsAFlatSiteOfTheReferenceSize) {
  const Scene plant = Scene::load(kScenes / "plant.glb");
  // DESIGN.md "Speed": the reference scene has about 234k triangles.
  EXPECT_GT(plant.triangle_count(), 220000u);
  EXPECT_LT(plant.triangle_count(), 250000u);
  for (const auto& [x, y] : {std::pair{0.0, -100.0}, {-170.0, 0.0}, {150.0, 105.0}, {-100.0, -120.0}}) {
    const auto ground = cast(plant, {x, y, 100.0}, {0, 0, -1});
    ASSERT_TRUE(ground) << x << ", " << y;
    EXPECT_NEAR(ground->distance, 100.0f, 0.05f) << x << ", " << y;
  }
  int retro = 0;
  for (unsigned g = 0; g < plant.geometry_count(); ++g) {
    const Material& m = plant.material(g);
    EXPECT_TRUE(m.reflectivity >= 0.0f && m.reflectivity <= 1.0f) << m.name;
    retro += m.retroreflective ? 1 : 0;
  }
  EXPECT_GE(retro, 1);
}

TEST(ShippedScenes, InspectionFlightIsAClosedDroneLapClearOfThePlant) {
  const std::vector<TumRow> flight = read_tum(kScenes / "plant_inspection.tum");
  ASSERT_GT(flight.size(), 100u);
  const double duration = flight.back().time_s - flight.front().time_s;
  EXPECT_GT(duration, 120.0);
  EXPECT_LT(duration, 600.0);
  EXPECT_LT((flight.back().position - flight.front().position).norm(), 1e-3);
  EXPECT_LT(flight.back().rotation.angularDistance(flight.front().rotation), 1e-6);
  const Scene plant = Scene::load(kScenes / "plant.glb");
  for (size_t i = 1; i < flight.size(); ++i) {
    const double dt = flight[i].time_s - flight[i - 1].time_s;
    const Eigen::Vector3d velocity = (flight[i].position - flight[i - 1].position) / dt;
    ASSERT_LE(dt, 0.1 + 1e-9) << i;
    ASSERT_NEAR(velocity.norm(), 4.0, 1.0) << i;
    ASSERT_GE(flight[i].position.z(), 5.0) << i;
    ASSERT_LE(flight[i].position.z(), 20.0) << i;
    // Looking forward: the sensor's x axis follows the motion, its z axis stays near vertical.
    const Eigen::Matrix3d world_from_sensor = flight[i].rotation.toRotationMatrix();
    ASSERT_GT(world_from_sensor.col(0).dot(velocity.normalized()), std::cos(10.0 * M_PI / 180.0)) << i;
    ASSERT_GT(world_from_sensor(2, 2), std::cos(10.0 * M_PI / 180.0)) << i;
    if (i % 10 != 0) continue;
    for (int axis = 0; axis < 6; ++axis) {
      const Eigen::Vector3d d = (axis < 3 ? 1.0 : -1.0) * Eigen::Vector3d::Unit(axis % 3);
      ASSERT_FALSE(cast(plant, flight[i].position, d, 3.0f)) << "within 3 m of the plant at pose " << i;
    }
  }
}

TEST(ShippedScenes, CalibrationHallShowsEveryTargetFromTheStaticPose) {
  const TumRow pose = read_tum(kScenes / "calibration_hall_static.tum").at(0);
  const Scene hall = Scene::load(kScenes / "calibration_hall.glb");
  EXPECT_GE(hall.bounds().sizes().x(), 120.0);
  std::vector<double> ranges, reflectivities, incidences;
  int retro = 0;
  for (unsigned g = 0; g < hall.geometry_count(); ++g) {
    const Material& m = hall.material(g);
    double range, az, el, rho, inc;
    if (std::sscanf(m.name.c_str(), "target_r%lf_az%lf_el%lf_rho%lf_inc%lf", &range, &az, &el, &rho, &inc) != 5)
      continue;
    SCOPED_TRACE(m.name);
    const double a = az * M_PI / 180.0, e = el * M_PI / 180.0;
    const Eigen::Vector3d sensor_direction(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
    const auto hit = cast(hall, pose.position, pose.rotation * sensor_direction);
    ASSERT_TRUE(hit);
    EXPECT_EQ(hit->geom_id, g) << "hidden by " << hall.material(hit->geom_id).name;
    EXPECT_NEAR(hit->distance, range, 1e-3 * range);
    EXPECT_FLOAT_EQ(m.reflectivity, static_cast<float>(rho));
    EXPECT_LT(std::abs(el), 15.0);  // inside the ±22.5° of an OS1 with room for the board
    ranges.push_back(range);
    reflectivities.push_back(rho);
    incidences.push_back(inc);
    retro += m.retroreflective ? 1 : 0;
  }
  ASSERT_FALSE(ranges.empty());
  EXPECT_LE(*std::min_element(ranges.begin(), ranges.end()), 1.0);
  EXPECT_GE(*std::max_element(ranges.begin(), ranges.end()), 100.0);
  EXPECT_LE(*std::min_element(reflectivities.begin(), reflectivities.end()), 0.05 + 1e-9);
  EXPECT_GE(*std::max_element(reflectivities.begin(), reflectivities.end()), 0.9 - 1e-9);
  EXPECT_GE(*std::max_element(incidences.begin(), incidences.end()), 75.0);
  EXPECT_GE(retro, 1);
}

}  // namespace
}  // namespace lidartwin
