// One column of beams cast with Embree: 16-ray coherent packets, as DESIGN.md's raw reference.
#include "lidartwin/caster/column_caster.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <embree3/rtcore.h>

namespace lidartwin {
namespace {

constexpr int kPacket = 16;

// The world ray of each beam: world_from_sensor applied to the SDK rays of this column (7.2).
struct WorldTransform {
  Eigen::Matrix3f rotation;
  Eigen::Vector3f translation;
};

void fill_packet(const BeamRay* rays, int count, const WorldTransform& pose, float tfar, RTCRayHit16& packet,
                 int* valid) {
  for (int i = 0; i < kPacket; ++i) {
    const BeamRay& ray = rays[std::min(i, count - 1)];  // the tail lanes repeat the last ray, masked off
    const Eigen::Vector3f origin = pose.rotation * ray.origin_m + pose.translation;
    const Eigen::Vector3f direction = pose.rotation * ray.direction;
    packet.ray.org_x[i] = origin.x();
    packet.ray.org_y[i] = origin.y();
    packet.ray.org_z[i] = origin.z();
    packet.ray.dir_x[i] = direction.x();
    packet.ray.dir_y[i] = direction.y();
    packet.ray.dir_z[i] = direction.z();
    packet.ray.tnear[i] = ray.range_offset_m;  // start at the physical beam origin
    packet.ray.tfar[i] = tfar;
    packet.ray.time[i] = 0.0f;
    packet.ray.mask[i] = 0xFFFFFFFFu;
    packet.ray.id[i] = static_cast<unsigned>(i);
    packet.ray.flags[i] = 0;
    packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    packet.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    valid[i] = i < count ? -1 : 0;
  }
}

void read_hits(const RTCRayHit16& packet, const Scene& scene, std::span<IdealReturn> out) {
  for (size_t i = 0; i < out.size(); ++i) {
    IdealReturn& ideal = out[i];
    ideal = IdealReturn{};
    const unsigned geom_id = packet.hit.geomID[i];
    if (geom_id == RTC_INVALID_GEOMETRY_ID) continue;
    const float nx = packet.hit.Ng_x[i], ny = packet.hit.Ng_y[i], nz = packet.hit.Ng_z[i];
    const float dot = nx * packet.ray.dir_x[i] + ny * packet.ray.dir_y[i] + nz * packet.ray.dir_z[i];
    const float norm2 = nx * nx + ny * ny + nz * nz;
    const Material& material = scene.material(geom_id);
    ideal.range_m = packet.ray.tfar[i];
    ideal.cos_incidence = norm2 > 0.0f ? std::min(1.0f, std::abs(dot) / std::sqrt(norm2)) : 1.0f;
    ideal.reflectivity = material.reflectivity;
    ideal.specular = material.specular;
    ideal.material_id = geom_id;
    ideal.retroreflective = material.retroreflective ? 1 : 0;
  }
}

bool depth_step(const IdealReturn& a, const IdealReturn& b) {
  if (a.hit() != b.hit()) return true;
  if (!a.hit()) return false;
  return std::abs(a.range_m - b.range_m) > std::max(0.3f, 0.05f * std::max(a.range_m, b.range_m));
}

}  // namespace

void mark_vertical_edges(std::span<IdealReturn> column) {
  const size_t n = column.size();
  for (size_t r = 0; r < n; ++r) {
    const bool above = r > 0 && depth_step(column[r], column[r - 1]);
    const bool below = r + 1 < n && depth_step(column[r], column[r + 1]);
    column[r].edge = (above || below) ? 1 : 0;
  }
}

ColumnCaster::ColumnCaster(const Scene& scene, const BeamGeometry& geometry, float max_range_m)
    : scene_(scene), geometry_(geometry), max_range_m_(max_range_m) {}

void ColumnCaster::cast(int measurement_id, const Pose& world_from_sensor, std::span<IdealReturn> out) const {
  assert(static_cast<int>(out.size()) == geometry_.rows());
  const WorldTransform pose{world_from_sensor.rotation.toRotationMatrix().cast<float>(),
                            world_from_sensor.translation.cast<float>()};
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // the beams of a column are coherent
  const BeamRay* rays = &geometry_.ray(0, measurement_id);
  const int rows = geometry_.rows();
  for (int first = 0; first < rows; first += kPacket) {
    const int count = std::min(kPacket, rows - first);
    alignas(64) RTCRayHit16 packet;
    alignas(64) int valid[kPacket];
    fill_packet(rays + first, count, pose, max_range_m_, packet, valid);
    rtcIntersect16(valid, scene_.embree_scene(), &context, &packet);
    read_hits(packet, scene_, out.subspan(static_cast<size_t>(first), static_cast<size_t>(count)));
  }
  mark_vertical_edges(out);
}

}  // namespace lidartwin
