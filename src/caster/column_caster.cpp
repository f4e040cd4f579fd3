// Columns of beams cast with Embree: 16-ray coherent packets, one row of 16 neighbouring columns each.
// The work around the cast is written as plain 16-lane loops so it vectorizes: the emulator's
// budget per pixel after the cast is a few nanoseconds (DESIGN.md "Speed").
#include "lidartwin/caster/column_caster.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <stdexcept>

#include <embree3/rtcore.h>

#include "caster/lane_kernels.h"

namespace lidartwin {
namespace {

constexpr int kLanes = RayStrip::kColumns;
static_assert(kLanes == caster_detail::kLanes);
constexpr size_t kMaxRows = 128;  // beams of the largest Ouster sensor

// world_from_sensor as plain floats: rotation row-major, then translation.
struct WorldTransform {
  float r[9] = {};
  float t[3] = {};
  WorldTransform() = default;
  explicit WorldTransform(const Pose& pose) {
    const Eigen::Matrix3d m = pose.rotation.toRotationMatrix();
    for (int i = 0; i < 9; ++i) r[i] = static_cast<float>(m(i / 3, i % 3));
    for (int i = 0; i < 3; ++i) t[i] = static_cast<float>(pose.translation[i]);
  }
};

// Each lane's world_from_sensor, structure of arrays: lane i's ray moves by its own column's pose.
struct LaneTransforms {
  alignas(64) float r[9][kLanes];
  alignas(64) float t[3][kLanes];
  void set(int lane, const WorldTransform& w) {
    for (int j = 0; j < 9; ++j) r[j][lane] = w.r[j];
    for (int j = 0; j < 3; ++j) t[j][lane] = w.t[j];
  }
};

// Sensor-frame rays into the world (protocol doc 7.2: the SDK's rays, moved by the pose of their
// column's time). Directions add a zero translation, as origins add theirs.
void transform_lanes(const RayStrip& rays, const LaneTransforms& w, RTCRay16& ray) {
  caster_detail::transform_lanes({{rays.org_x, rays.org_y, rays.org_z}, {rays.dir_x, rays.dir_y, rays.dir_z}}, w.r, w.t,
                                 {{ray.org_x, ray.org_y, ray.org_z}, {ray.dir_x, ray.dir_y, ray.dir_z}});
}

// The fields every lane shares; tnear starts each ray at the physical beam origin.
void init_packet(float tnear, float tfar, RTCRayHit16& packet) {
  RTCRay16& ray = packet.ray;
  for (int i = 0; i < kLanes; ++i) {
    ray.tnear[i] = tnear;
    ray.tfar[i] = tfar;
    ray.time[i] = 0.0f;
    ray.mask[i] = 0xFFFFFFFFu;
    ray.id[i] = static_cast<unsigned>(i);
    ray.flags[i] = 0;
    packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    packet.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
}

// Every pixel starts from this (copied from read-only memory: `ideal = IdealReturn{}` built the
// 44 bytes on the stack with overlapping stores and copied them out through loads that spanned two
// of them, a store-forwarding stall per pixel that was 70 % of the caster's own time).
constexpr IdealReturn kNoReturn{};

// Where lane i's ray came from: column (of the group) and the row's place in cast order.
struct LaneSource {
  std::array<uint8_t, kLanes> column;
  std::array<uint16_t, kLanes> k;
};

// Where each hit lies, measured in this project's own arithmetic: the distance along the ray to the
// hit triangle's plane and that triangle's normal, from its vertices (the scene's TrianglePlane). Embree decides which
// triangle a ray hits; its t and Ng come from kernels that differ between SSE, AVX2 and AVX-512 in their last bits (one
// pixel in ten thousand read a different millimetre), so the same scene cast on two CPUs would not give the same
// capture. The plane distance in double, without fused multiply-adds (cmake/InstructionSet.cmake), is the same on every
// CPU. A ray grazing its triangle's plane (dot(d, n) = 0) keeps Embree's t.
void measure_hits(const RTCRayHit16& packet, const TriangleMesh* meshes, int used, float* t, float* nx, float* ny,
                  float* nz) {
  for (int i = 0; i < kLanes; ++i) {
    const auto lane = static_cast<size_t>(i);
    t[lane] = packet.ray.tfar[lane];
    nx[lane] = packet.hit.Ng_x[lane];
    ny[lane] = packet.hit.Ng_y[lane];
    nz[lane] = packet.hit.Ng_z[lane];
    const unsigned geom_id = packet.hit.geomID[lane];
    if (i >= used || geom_id == RTC_INVALID_GEOMETRY_ID) continue;
    const TrianglePlane& plane = meshes[geom_id].planes[packet.hit.primID[lane]];
    const Eigen::Vector3d v0(plane.corner[0], plane.corner[1], plane.corner[2]);
    const Eigen::Vector3d n(plane.normal[0], plane.normal[1], plane.normal[2]);
    const Eigen::Vector3d origin(packet.ray.org_x[lane], packet.ray.org_y[lane], packet.ray.org_z[lane]);
    const Eigen::Vector3d direction(packet.ray.dir_x[lane], packet.ray.dir_y[lane], packet.ray.dir_z[lane]);
    const double along = direction.dot(n);
    if (along == 0.0) continue;
    t[lane] = static_cast<float>((v0 - origin).dot(n) / along);
    nx[lane] = static_cast<float>(n.x());
    ny[lane] = static_cast<float>(n.y());
    nz[lane] = static_cast<float>(n.z());
  }
}

// The first `used` lanes' hits into their columns' rows; sets retro[c] where a hit is
// retroreflective.
void read_hits(const RTCRayHit16& packet, const ColumnCaster::SurfaceOptics* optics, const TriangleMesh* meshes,
               const BeamGeometry& geometry, const LaneSource& source, int used,
               std::span<const ColumnCaster::Column> group, bool* retro) {
  alignas(64) float t[kLanes];
  alignas(64) float nx[kLanes];
  alignas(64) float ny[kLanes];
  alignas(64) float nz[kLanes];
  measure_hits(packet, meshes, used, t, nx, ny, nz);
  // |cos| of the incidence angle, all lanes at once; a degenerate normal (NaN) or rounding above 1
  // gives 1.
  alignas(64) float cos_incidence[kLanes];
  caster_detail::cos_incidence_lanes(nx, ny, nz, packet.ray.dir_x, packet.ray.dir_y, packet.ray.dir_z, cos_incidence);
  for (int i = 0; i < used; ++i) {
    const auto lane = static_cast<size_t>(i);
    const auto row = static_cast<uint16_t>(geometry.cast_row(source.k[lane]));
    IdealReturn& ideal = group[source.column[lane]].out[row];
    ideal = kNoReturn;
    ideal.beam = row;
    const unsigned geom_id = packet.hit.geomID[lane];
    if (geom_id == RTC_INVALID_GEOMETRY_ID) continue;
    const ColumnCaster::SurfaceOptics& material = optics[geom_id];
    ideal.range_m = t[lane];
    ideal.cos_incidence = cos_incidence[lane];
    ideal.reflectivity = material.reflectivity;
    ideal.specular = material.specular;
    ideal.material_id = geom_id;
    ideal.retroreflective = material.retroreflective;
    retro[source.column[lane]] |= material.retroreflective != 0;
  }
}

}  // namespace

bool depth_step(float a, float b) {
  const bool hit_a = a > 0.0f, hit_b = b > 0.0f;
  if (hit_a != hit_b) return true;
  return hit_a && std::abs(a - b) > std::max(0.3f, 0.05f * std::max(a, b));
}

void mark_vertical_edges(std::span<IdealReturn> column) {
  const size_t n = column.size();
  if (n == 0) return;
  // Profiles have 16 to 128 beams (profile_parse.cpp); a longer column is a caller's bug.
  if (n > kMaxRows) throw std::length_error("mark_vertical_edges: a column has at most 128 rows");
  // step[r] = 1 when rows r and r + 1 differ by a depth step or in hit/miss (depth_step's rule);
  // then each row is an edge when the step above or below it is. Ranges are copied out of the
  // returns first, so the step loop runs on plain arrays, vectorized.
  alignas(64) float range[kMaxRows + 1];
  alignas(64) uint8_t step[kMaxRows + 1];
  for (size_t r = 0; r < n; ++r) range[r] = column[r].range_m;
  caster_detail::depth_steps(range, n, step);
  column[0].edge = n > 1 ? step[0] : 0;
  for (size_t r = 1; r + 1 < n; ++r) column[r].edge = step[r - 1] | step[r];
  if (n > 1) column[n - 1].edge = step[n - 2];
}

void mark_retro_neighbours(std::span<IdealReturn> column) {
  // Most columns see no retroreflector: one pass over the flags, and nothing more to do.
  std::array<int, kMaxRows> retros;
  size_t count = 0;
  for (size_t r = 0; r < column.size() && count < kMaxRows; ++r) {
    column[r].retro_rows = 0;
    column[r].retro_range_m = 0.0f;
    if (column[r].retroreflective) retros[count++] = static_cast<int>(r);
  }
  if (count == 0) return;
  const int reach = IdealReturn::kRetroReachRows;
  size_t next = 0;  // the first retro row at or below r
  for (size_t r = 0; r < column.size(); ++r) {
    const int row = static_cast<int>(r);
    while (next < count && retros[next] < row) ++next;
    IdealReturn& pixel = column[r];
    if (pixel.retroreflective) continue;
    const int above = next > 0 ? row - retros[next - 1] : reach + 1;
    const int below = next < count ? retros[next] - row : reach + 1;
    const int distance = std::min(above, below);
    if (distance > reach) continue;
    pixel.retro_rows = static_cast<uint8_t>(distance);
    pixel.retro_range_m = column[static_cast<size_t>(above <= below ? row - above : row + below)].range_m;
  }
}

void choose_edge_partner(IdealReturn& pixel, std::span<const Neighbour> neighbours) {
  pixel.partner_range_m = pixel.partner_reflectance = pixel.partner_spacing_rad = 0.0f;
  if (!pixel.hit()) return;
  // A surface seen at incidence theta changes range by about r * spacing * tan(theta) from one
  // beam to the next: a floor at grazing incidence looks stepped to a fixed threshold, but it is
  // one surface, whose spread E4 models. A partner must lie beyond twice that.
  const float c = std::clamp(pixel.cos_incidence, 0.05f, 1.0f);
  const float slope = pixel.range_m * std::sqrt(1.0f - c * c) / c;  // r tan(theta), per radian
  float largest = 0.0f;
  for (const Neighbour& n : neighbours) {
    if (n.ideal == nullptr || !n.ideal->hit() || !depth_step(pixel.range_m, n.ideal->range_m)) continue;
    const float step = std::abs(n.ideal->range_m - pixel.range_m);
    if (step <= 2.0f * slope * n.spacing_rad || step <= largest) continue;
    largest = step;
    pixel.partner_range_m = n.ideal->range_m;
    pixel.partner_reflectance = n.ideal->reflectivity * n.ideal->cos_incidence;
    pixel.partner_spacing_rad = n.spacing_rad;
  }
}

void find_edge_partners(std::span<IdealReturn> column, std::span<const IdealReturn> left,
                        std::span<const IdealReturn> right, const BeamGeometry& geometry) {
  const size_t rows = column.size();
  if (rows > kMaxRows) throw std::length_error("find_edge_partners: a column has at most 128 rows");
  static_assert(kMaxRows == caster_detail::kPartnerRows);
  // choose_edge_partner for every row at once (caster_detail::edge_partners), from the fields it
  // reads copied out by row; the row above is the column's ranges one place earlier, the row
  // below one place later, a missing neighbour reads as a miss (range 0) as it does there.
  constexpr size_t kPad = kMaxRows + 2;
  alignas(64) float range[kPad] = {}, reflectance[kPad] = {};
  alignas(64) float cos_incidence[kMaxRows] = {};
  alignas(64) float side_range[2][kMaxRows] = {}, side_reflectance[2][kMaxRows] = {};
  alignas(64) float up_spacing[kMaxRows] = {}, down_spacing[kMaxRows] = {}, side_spacing[kMaxRows] = {};
  for (size_t r = 0; r < rows; ++r) {
    const int row = static_cast<int>(r);
    range[r + 1] = column[r].range_m;
    reflectance[r + 1] = column[r].reflectivity * column[r].cos_incidence;
    cos_incidence[r] = column[r].cos_incidence;
    if (r > 0) up_spacing[r] = geometry.row_spacing_rad(row - 1);
    if (r + 1 < rows) down_spacing[r] = geometry.row_spacing_rad(row);
    side_spacing[r] = geometry.column_spacing_rad(row);
  }
  const std::span<const IdealReturn> sides[2] = {left, right};
  for (size_t side = 0; side < 2; ++side) {
    if (sides[side].empty()) continue;
    for (size_t r = 0; r < rows; ++r) {
      side_range[side][r] = sides[side][r].range_m;
      side_reflectance[side][r] = sides[side][r].reflectivity * sides[side][r].cos_incidence;
    }
  }
  const caster_detail::PartnerCandidates candidates{
      {range, range + 2, side_range[0], side_range[1]},
      {reflectance, reflectance + 2, side_reflectance[0], side_reflectance[1]},
      {up_spacing, down_spacing, side_spacing, side_spacing}};
  alignas(64) float partner_range[kMaxRows], partner_reflectance[kMaxRows], partner_spacing[kMaxRows];
  caster_detail::edge_partners(range + 1, cos_incidence, candidates,
                               {partner_range, partner_reflectance, partner_spacing});
  for (size_t r = 0; r < rows; ++r) {
    column[r].partner_range_m = partner_range[r];
    column[r].partner_reflectance = partner_reflectance[r];
    column[r].partner_spacing_rad = partner_spacing[r];
  }
}

ColumnCaster::ColumnCaster(const Scene& scene, const BeamGeometry& geometry, float max_range_m)
    : scene_(scene), geometry_(geometry), max_range_m_(max_range_m) {
  for (unsigned id = 0; id < scene.geometry_count(); ++id) {
    const Material& m = scene.material(id);
    optics_.push_back({m.reflectivity, m.specular, static_cast<uint8_t>(m.retroreflective ? 1 : 0)});
    meshes_.push_back(scene.mesh(id));
  }
}

void ColumnCaster::cast(int measurement_id, const Pose& world_from_sensor, std::span<IdealReturn> out) const {
  const Column column{measurement_id, &world_from_sensor, out};
  cast_group({&column, 1});
}

void ColumnCaster::cast(std::span<const Column> columns) const {
  for (size_t first = 0; first < columns.size(); first += kGroupColumns) {
    cast_group(columns.subspan(first, std::min(kGroupColumns, columns.size() - first)));
  }
}

// Lane sequence: slot s is row cast_row(s / n) of column s % n, n columns in the group (less the
// rows a column cast beside hits skips). Sixteen neighbouring columns aligned to a strip (the
// renderer's blocks) cast strip by strip, straight from the geometry; any other group gathers its
// lanes' rays (fewer columns: several rows each).
void ColumnCaster::cast_group(std::span<const Column> group) const {
  const int n = static_cast<int>(group.size());
  assert(n >= 1 && n <= kLanes);
  const int first_id = group[0].measurement_id;
  bool whole_strip = n == kLanes && first_id % kLanes == 0;
  std::array<WorldTransform, kLanes> world;
  for (int c = 0; c < n; ++c) {
    const Column& column = group[static_cast<size_t>(c)];
    assert(static_cast<int>(column.out.size()) == geometry_.rows());
    world[static_cast<size_t>(c)] = WorldTransform(*column.world_from_sensor);
    whole_strip = whole_strip && column.measurement_id == first_id + c;
  }
  alignas(64) LaneTransforms lanes;
  LaneSource source{};
  if (whole_strip) {
    for (int i = 0; i < kLanes; ++i) {
      lanes.set(i, world[static_cast<size_t>(i)]);
      source.column[static_cast<size_t>(i)] = static_cast<uint8_t>(i);
    }
  }
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // one row of neighbouring columns
  // A column cast beside hits skips the rows where they missed: those slots are not cast.
  const auto wanted = [&](int c, int k) {
    const auto& beside = group[static_cast<size_t>(c)].beside_hits;
    return beside.empty() || beside[static_cast<size_t>(geometry_.cast_row(k))].hit();
  };
  int slots = n * geometry_.rows();
  if (!whole_strip) {
    slots = 0;
    for (int c = 0; c < n; ++c) {
      const Column& column = group[static_cast<size_t>(c)];
      if (column.beside_hits.empty()) {
        slots += geometry_.rows();
        continue;
      }
      assert(column.beside_hits.size() == column.out.size());
      for (size_t row = 0; row < column.out.size(); ++row) {
        if (column.beside_hits[row].hit()) {
          ++slots;
        } else {
          column.out[row] = kNoReturn;
          column.out[row].beam = static_cast<uint16_t>(row);
        }
      }
    }
  }
  std::array<bool, kLanes> retro{};
  int next_column = 0, next_k = 0;  // the next slot's source
  const auto skip_unwanted = [&] {
    while (next_k < geometry_.rows() && !wanted(next_column, next_k)) {
      if (++next_column == n) next_column = 0, ++next_k;
    }
  };
  skip_unwanted();
  for (int first = 0; first < slots; first += kLanes) {
    alignas(64) RTCRayHit16 packet;
    alignas(64) int valid[kLanes];
    init_packet(geometry_.range_offset_m(), max_range_m_, packet);
    const int used = std::min(kLanes, slots - first);
    if (whole_strip) {
      const int k = first / kLanes;
      source.k.fill(static_cast<uint16_t>(k));
      std::fill(valid, valid + kLanes, -1);
      transform_lanes(geometry_.strip(first_id / kLanes, k), lanes, packet.ray);
      // The next strip (384 bytes) is fetched while Embree casts this one: read after its
      // traversal had filled the caches, it missed.
      if (k + 1 < geometry_.rows()) {
        const auto* next = reinterpret_cast<const char*>(&geometry_.strip(first_id / kLanes, k + 1));
        for (size_t offset = 0; offset < sizeof(RayStrip); offset += 64) __builtin_prefetch(next + offset, 0, 2);
      }
    } else {
      alignas(64) RayStrip gathered;
      for (int i = 0; i < kLanes; ++i) {
        const auto lane = static_cast<size_t>(i);
        if (i < used) {
          source.column[lane] = static_cast<uint8_t>(next_column);
          source.k[lane] = static_cast<uint16_t>(next_k);
          if (++next_column == n) next_column = 0, ++next_k;
          skip_unwanted();
        } else {  // past the last slot: repeat the last, masked off
          source.column[lane] = source.column[lane - 1];
          source.k[lane] = source.k[lane - 1];
        }
        valid[i] = i < used ? -1 : 0;
        const int m = group[source.column[lane]].measurement_id;
        const RayStrip& strip = geometry_.strip(m / kLanes, source.k[lane]);
        const auto j = static_cast<size_t>(m % kLanes);
        gathered.org_x[lane] = strip.org_x[j], gathered.org_y[lane] = strip.org_y[j];
        gathered.org_z[lane] = strip.org_z[j], gathered.dir_x[lane] = strip.dir_x[j];
        gathered.dir_y[lane] = strip.dir_y[j], gathered.dir_z[lane] = strip.dir_z[j];
        lanes.set(i, world[source.column[lane]]);
      }
      transform_lanes(gathered, lanes, packet.ray);
    }
    rtcIntersect16(valid, scene_.embree_scene(), &context, &packet);
    read_hits(packet, optics_.data(), meshes_.data(), geometry_, source, used, group, retro.data());
  }
  for (size_t c = 0; c < group.size(); ++c) {
    mark_vertical_edges(group[c].out);
    // Without a retroreflector in the column every pixel keeps kNoReturn's "none near" (most columns).
    if (retro[c]) mark_retro_neighbours(group[c].out);
  }
}

}  // namespace lidartwin
