// Scene: the glTF triangles in one Embree 3 scene, one triangle geometry per placed primitive, so
// an Embree hit's geomID indexes the material table directly.
#include "lidartwin/scene/scene.h"

#include <cstring>
#include <stdexcept>
#include <vector>

#include <embree3/rtcore.h>

#include "lidartwin/error.h"
#include "scene/gltf_material.h"
#include "scene/gltf_reader.h"

namespace lidartwin {
namespace {

// Embree reports errors through a callback; keep the first so load() can throw it.
void remember_error(void* user, RTCError, const char* message) {
  auto* first = static_cast<std::string*>(user);
  if (first->empty()) *first = message != nullptr ? message : "unknown Embree error";
}

RTCGeometry make_geometry(RTCDevice device, const scene_detail::MeshPart& part, TriangleMesh& mesh) {
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  const size_t vertex_count = part.vertices.size() / 3;
  const size_t triangle_count = part.indices.size() / 3;
  // Embree pads these buffers itself (its SIMD loads read past the last vertex).
  void* vertices =
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertex_count);
  void* indices = rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t),
                                          triangle_count);
  if (vertices != nullptr) std::memcpy(vertices, part.vertices.data(), part.vertices.size() * sizeof(float));
  if (indices != nullptr) std::memcpy(indices, part.indices.data(), part.indices.size() * sizeof(uint32_t));
  mesh = {static_cast<const float*>(vertices), static_cast<const uint32_t*>(indices)};
  rtcCommitGeometry(geometry);
  return geometry;
}

// Each triangle's plane (TrianglePlane), in the arithmetic measure_hits used to do per hit.
std::vector<TrianglePlane> triangle_planes(const scene_detail::MeshPart& part) {
  std::vector<TrianglePlane> planes(part.indices.size() / 3);
  const auto vertex = [&part](uint32_t k) {
    const float* v = part.vertices.data() + size_t{3} * k;
    return Eigen::Vector3d(v[0], v[1], v[2]);
  };
  for (size_t j = 0; j < planes.size(); ++j) {
    const uint32_t* corner = part.indices.data() + 3 * j;
    const Eigen::Vector3d v0 = vertex(corner[0]);
    const Eigen::Vector3d n = (vertex(corner[1]) - v0).cross(vertex(corner[2]) - v0);
    planes[j] = {{n.x(), n.y(), n.z()},
                 {part.vertices[3 * corner[0]], part.vertices[3 * corner[0] + 1], part.vertices[3 * corner[0] + 2]}};
  }
  return planes;
}

}  // namespace

struct Scene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Material> materials;                 // glTF materials, then the default one
  std::vector<unsigned> material_of_geometry;      // geomID → index into materials
  std::vector<TriangleMesh> meshes;                // geomID → its buffers (Embree owns them) and planes
  std::vector<std::vector<TrianglePlane>> planes;  // geomID → its triangles' planes
  size_t triangles = 0;
  std::string embree_error;

  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
};

Scene Scene::load(const std::filesystem::path& path) {
  scene_detail::GltfContent content = scene_detail::read_gltf(path);
  if (content.parts.empty()) {
    throw InputError(path.string() +
                     ": no triangles (only TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN primitives "
                     "of the default scene are ray cast)");
  }
  auto impl = std::make_unique<Impl>();
  impl->device = rtcNewDevice(nullptr);
  if (impl->device == nullptr) throw std::runtime_error("Embree: rtcNewDevice failed");
  rtcSetDeviceErrorFunction(impl->device, &remember_error, &impl->embree_error);
  impl->scene = rtcNewScene(impl->device);
  rtcSetSceneFlags(impl->scene, RTC_SCENE_FLAG_NONE);
  // High quality: the scene is built once and cast millions of times (DESIGN.md "Speed").
  rtcSetSceneBuildQuality(impl->scene, RTC_BUILD_QUALITY_HIGH);
  impl->materials = std::move(content.materials);
  const auto default_material = static_cast<unsigned>(impl->materials.size());
  impl->materials.push_back(scene_detail::default_material());
  for (scene_detail::MeshPart& part : content.parts) {
    TriangleMesh mesh;
    RTCGeometry geometry = make_geometry(impl->device, part, mesh);
    const unsigned id = rtcAttachGeometry(impl->scene, geometry);
    rtcReleaseGeometry(geometry);  // the scene holds it, and so its buffers
    impl->material_of_geometry.resize(id + 1, default_material);
    impl->meshes.resize(id + 1);
    impl->planes.resize(id + 1);
    impl->planes[id] = triangle_planes(part);
    impl->meshes[id] = mesh;
    impl->material_of_geometry[id] = part.material < 0 ? default_material : static_cast<unsigned>(part.material);
    impl->triangles += part.indices.size() / 3;
    part = {};  // Embree holds its own copy now
  }
  for (size_t id = 0; id < impl->meshes.size(); ++id) impl->meshes[id].planes = impl->planes[id].data();
  rtcCommitScene(impl->scene);
  if (!impl->embree_error.empty()) throw std::runtime_error("Embree: " + impl->embree_error);
  return Scene(std::move(impl));
}

Scene::Scene(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Scene::~Scene() = default;
Scene::Scene(Scene&&) noexcept = default;
Scene& Scene::operator=(Scene&&) noexcept = default;

RTCSceneTy* Scene::embree_scene() const { return impl_->scene; }

const Material& Scene::material(unsigned geom_id) const {
  return impl_->materials[impl_->material_of_geometry.at(geom_id)];
}

std::optional<SceneHit> Scene::first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, float near_m,
                                         float far_m) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(origin.x());
  rh.ray.org_y = static_cast<float>(origin.y());
  rh.ray.org_z = static_cast<float>(origin.z());
  rh.ray.dir_x = static_cast<float>(direction.x());
  rh.ray.dir_y = static_cast<float>(direction.y());
  rh.ray.dir_z = static_cast<float>(direction.z());
  rh.ray.tnear = near_m;
  rh.ray.tfar = far_m;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  return SceneHit{rh.ray.tfar, rh.hit.geomID, rh.hit.primID, Eigen::Vector3f(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z)};
}

TriangleMesh Scene::mesh(unsigned geom_id) const { return impl_->meshes.at(geom_id); }
size_t Scene::triangle_count() const { return impl_->triangles; }
size_t Scene::geometry_count() const { return impl_->material_of_geometry.size(); }

Eigen::AlignedBox3d Scene::bounds() const {
  RTCBounds b;
  rtcGetSceneBounds(impl_->scene, &b);
  return Eigen::AlignedBox3d(Eigen::Vector3f(b.lower_x, b.lower_y, b.lower_z).cast<double>(),
                             Eigen::Vector3f(b.upper_x, b.upper_y, b.upper_z).cast<double>());
}

}  // namespace lidartwin
