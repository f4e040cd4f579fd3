// Columns of beams cast with Embree: 16-ray coherent packets, four rows of four columns each.
// The work around the cast is written as plain 16-lane loops so it vectorizes: the emulator's
// budget per pixel after the cast is a few nanoseconds (DESIGN.md "Speed").
#include "lidartwin/caster/column_caster.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <stdexcept>

#include <embree3/rtcore.h>

namespace lidartwin {
namespace {

constexpr int kLanes = 16;
constexpr int kQuadLanes = RayQuad::kLanes;
constexpr size_t kMaxRows = 128;  // beams of the largest Ouster sensor

// A depth step between two hits: farther apart than 0.3 m or 5 % of the farther range.
bool depth_step(float a, float b) { return std::abs(a - b) > std::max(0.3f, 0.05f * std::max(a, b)); }

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

// y = a*x0 + b*x1 + c*x2 + d over a quad's 4 lanes; restrict pointers and a fixed trip count let
// the compiler vectorize it.
void affine_lanes(const float* __restrict x0, const float* __restrict x1, const float* __restrict x2, const float* row,
                  float d, float* __restrict y) {
  const float a = row[0], b = row[1], c = row[2];
  for (int i = 0; i < kQuadLanes; ++i) y[i] = a * x0[i] + b * x1[i] + c * x2[i] + d;
}

// A quad's sensor-frame rays into lanes [first, first + 4) of the packet, in the world (protocol
// doc 7.2: the SDK's rays, moved by the pose of their column's time); `count` lanes are cast.
inline void fill_quad(const RayQuad& rays, const WorldTransform& w, int count, int first, RTCRayHit16& packet,
                      int* valid) {
  RTCRay16& ray = packet.ray;
  const auto f = static_cast<size_t>(first);
  affine_lanes(rays.org_x, rays.org_y, rays.org_z, w.r + 0, w.t[0], ray.org_x + f);
  affine_lanes(rays.org_x, rays.org_y, rays.org_z, w.r + 3, w.t[1], ray.org_y + f);
  affine_lanes(rays.org_x, rays.org_y, rays.org_z, w.r + 6, w.t[2], ray.org_z + f);
  affine_lanes(rays.dir_x, rays.dir_y, rays.dir_z, w.r + 0, 0.0f, ray.dir_x + f);
  affine_lanes(rays.dir_x, rays.dir_y, rays.dir_z, w.r + 3, 0.0f, ray.dir_y + f);
  affine_lanes(rays.dir_x, rays.dir_y, rays.dir_z, w.r + 6, 0.0f, ray.dir_z + f);
  for (int i = 0; i < kQuadLanes; ++i) valid[first + i] = i < count ? -1 : 0;
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

// |cos| of the incidence angle from the geometric normal, for all lanes at once; a degenerate
// normal (NaN) or rounding above 1 gives 1. Eigen arrays, because a plain loop with std::sqrt
// stays scalar under -fmath-errno.
void incidence_lanes(const RTCRayHit16& packet, float* out) {
  using Lanes = Eigen::Array<float, kLanes, 1>;
  using Map = Eigen::Map<const Lanes, Eigen::Aligned64>;
  const Map nx(packet.hit.Ng_x), ny(packet.hit.Ng_y), nz(packet.hit.Ng_z);
  const Lanes dot = nx * Map(packet.ray.dir_x) + ny * Map(packet.ray.dir_y) + nz * Map(packet.ray.dir_z);
  const Lanes c = dot.abs() / (nx.square() + ny.square() + nz.square()).sqrt();
  Eigen::Map<Lanes, Eigen::Aligned64> cosine(out);
  cosine = (c < 1.0f).select(c, Lanes::Ones());
}

// Every pixel starts from this (copied from read-only memory: `ideal = IdealReturn{}` built the
// 44 bytes on the stack with overlapping stores and copied them out through loads that spanned two
// of them, a store-forwarding stall per pixel that was 70 % of the caster's own time).
constexpr IdealReturn kNoReturn{};

// The hits of lanes [first, first + quad.count) into their rows of out; returns whether any is
// retroreflective.
bool read_hits(const RTCRayHit16& packet, const float* cos_incidence, const ColumnCaster::SurfaceOptics* optics,
               const QuadRows& quad, int first, std::span<IdealReturn> out) {
  bool retro = false;
  for (int lane = 0; lane < quad.count; ++lane) {
    const auto i = static_cast<size_t>(first + lane);
    const uint16_t row = quad.rows[lane];
    IdealReturn& ideal = out[row];
    ideal = kNoReturn;
    ideal.beam = row;
    const unsigned geom_id = packet.hit.geomID[i];
    if (geom_id == RTC_INVALID_GEOMETRY_ID) continue;
    const ColumnCaster::SurfaceOptics& material = optics[geom_id];
    ideal.range_m = packet.ray.tfar[i];
    ideal.cos_incidence = cos_incidence[i];
    ideal.reflectivity = material.reflectivity;
    ideal.specular = material.specular;
    ideal.material_id = geom_id;
    ideal.retroreflective = material.retroreflective;
    retro |= material.retroreflective != 0;
  }
  return retro;
}

}  // namespace

void mark_vertical_edges(std::span<IdealReturn> column) {
  const size_t n = column.size();
  if (n == 0) return;
  // Profiles have 16 to 128 beams (profile_parse.cpp); a longer column is a caller's bug.
  if (n > kMaxRows) throw std::length_error("mark_vertical_edges: a column has at most 128 rows");
  // step[r] = 1 when rows r and r + 1 differ by a depth step or in hit/miss; then each row is an
  // edge when the step above or below it is. Ranges are copied out of the returns first, so the
  // step loop runs on plain arrays without branches and vectorizes.
  alignas(64) float range[kMaxRows + 1];
  alignas(64) uint8_t step[kMaxRows + 1];
  for (size_t r = 0; r < n; ++r) range[r] = column[r].range_m;
  for (size_t r = 0; r + 1 < n; ++r) {
    const float a = range[r], b = range[r + 1];
    const bool hit_a = a > 0.0f, hit_b = b > 0.0f;
    step[r] = static_cast<uint8_t>((hit_a != hit_b) | (hit_a & hit_b & depth_step(a, b)));
  }
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
  // The neighbours' own fields are read before any partner is written: only partner_* change.
  for (size_t r = 0; r < rows; ++r) {
    const int row = static_cast<int>(r);
    const std::array<Neighbour, 4> neighbours{{
        {r > 0 ? &column[r - 1] : nullptr, r > 0 ? geometry.row_spacing_rad(row - 1) : 0.0f},
        {r + 1 < rows ? &column[r + 1] : nullptr, r + 1 < rows ? geometry.row_spacing_rad(row) : 0.0f},
        {left.empty() ? nullptr : &left[r], geometry.column_spacing_rad(row)},
        {right.empty() ? nullptr : &right[r], geometry.column_spacing_rad(row)},
    }};
    choose_edge_partner(column[r], neighbours);
  }
}

ColumnCaster::ColumnCaster(const Scene& scene, const BeamGeometry& geometry, float max_range_m)
    : scene_(scene), geometry_(geometry), max_range_m_(max_range_m) {
  for (unsigned id = 0; id < scene.geometry_count(); ++id) {
    const Material& m = scene.material(id);
    optics_.push_back({m.reflectivity, m.specular, static_cast<uint8_t>(m.retroreflective ? 1 : 0)});
  }
}

void ColumnCaster::cast(int measurement_id, const Pose& world_from_sensor, std::span<IdealReturn> out) const {
  const Column column{measurement_id, &world_from_sensor, out};
  cast_group({&column, 1});
}

void ColumnCaster::cast(std::span<const Column> columns) const {
  for (size_t first = 0; first < columns.size(); first += kColumnsPerPacket) {
    cast_group(columns.subspan(first, std::min(kColumnsPerPacket, columns.size() - first)));
  }
}

// Packet k holds slots 4k .. 4k + 3, slot s being quad s / n of column s % n: with four columns,
// the same quad of each; with fewer, neighbouring quads of the same columns (one column: 16 rows
// of one azimuth offset, as fast as its 16 consecutive rows).
void ColumnCaster::cast_group(std::span<const Column> group) const {
  const int n = static_cast<int>(group.size());
  assert(n >= 1 && n <= static_cast<int>(kColumnsPerPacket));
  std::array<WorldTransform, kColumnsPerPacket> world;
  for (int c = 0; c < n; ++c) {
    const Column& column = group[static_cast<size_t>(c)];
    assert(static_cast<int>(column.out.size()) == geometry_.rows());
    world[static_cast<size_t>(c)] = WorldTransform(*column.world_from_sensor);
  }
  // Slot s of the group is quad s / n of column s % n, counted up without a division.
  struct Slot {
    int column = 0;
    int quad = 0;
  };
  const auto next_slot = [n](Slot slot) { return ++slot.column == n ? Slot{0, slot.quad + 1} : slot; };
  const auto quad_of = [&](Slot slot) -> const RayQuad& {
    return geometry_.quad(group[static_cast<size_t>(slot.column)].measurement_id, slot.quad);
  };
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // neighbouring beams of neighbouring columns
  constexpr int kSlots = kLanes / kQuadLanes;
  const int slots = n * geometry_.quads_per_column();
  std::array<bool, kColumnsPerPacket> retro{};
  Slot first{};
  for (int first_slot = 0; first_slot < slots; first_slot += kSlots) {
    alignas(64) RTCRayHit16 packet;
    alignas(64) int valid[kLanes];
    init_packet(geometry_.range_offset_m(), max_range_m_, packet);
    const int used = std::min(kSlots, slots - first_slot);
    std::array<Slot, kSlots> slot;
    slot[0] = first;
    for (int k = 1; k < kSlots; ++k) slot[k] = k < used ? next_slot(slot[k - 1]) : slot[k - 1];  // repeats: masked off
    first = next_slot(slot[kSlots - 1]);
    // The next packet's rays are fetched while Embree casts this one: read after its traversal
    // had filled the caches, they missed (a third of the caster's own time).
    Slot ahead = first;
    for (int k = 0; k < kSlots && ahead.quad < geometry_.quads_per_column(); ++k, ahead = next_slot(ahead)) {
      const auto* bytes = reinterpret_cast<const char*>(&quad_of(ahead));  // 96 bytes: two lines at most
      __builtin_prefetch(bytes, 0, 2);
      __builtin_prefetch(bytes + sizeof(RayQuad) - 1, 0, 2);
    }
    for (int k = 0; k < kSlots; ++k) {
      const int count = k < used ? geometry_.quad_rows(slot[k].quad).count : 0;
      fill_quad(quad_of(slot[k]), world[static_cast<size_t>(slot[k].column)], count, k * kQuadLanes, packet, valid);
    }
    rtcIntersect16(valid, scene_.embree_scene(), &context, &packet);
    alignas(64) float cos_incidence[kLanes];
    incidence_lanes(packet, cos_incidence);
    for (int k = 0; k < used; ++k) {
      const auto c = static_cast<size_t>(slot[k].column);
      retro[c] |= read_hits(packet, cos_incidence, optics_.data(), geometry_.quad_rows(slot[k].quad), k * kQuadLanes,
                            group[c].out);
    }
  }
  for (size_t c = 0; c < group.size(); ++c) {
    mark_vertical_edges(group[c].out);
    // Without a retroreflector in the column every pixel keeps kNoReturn's "none near" (most columns).
    if (retro[c]) mark_retro_neighbours(group[c].out);
  }
}

}  // namespace lidartwin
