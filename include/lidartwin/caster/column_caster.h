#pragma once
// Casts the beams of columns, each at its own pose, with Embree (16-ray coherent packets).
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/caster/ideal_return.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

class ColumnCaster {
 public:
  // Hits farther than max_range_m from the virtual origin are misses (Embree's tfar).
  ColumnCaster(const Scene& scene, const BeamGeometry& geometry,
               float max_range_m = std::numeric_limits<float>::infinity());
  // One column to cast: its rays from its own pose (the pose of the column's time), its returns
  // into out (out.size() == geometry.rows()). The pose by pointer: the renderer's per-column
  // poses (or their moved copies) stay where they are.
  struct Column {
    int measurement_id;
    const Pose* world_from_sensor;
    std::span<IdealReturn> out;
    // When given (a column already cast, of out's size), only the rows where it hit are cast, and
    // the others read as misses: E6 needs a column beside a block only where the block's edge hit.
    std::span<const IdealReturn> beside_hits = {};
  };
  // Casts the columns 16 at a time: a packet holds one row of the 16 (a RayStrip when they are 16
  // neighbours aligned as the geometry stores them, as the renderer's blocks are), which Embree
  // traverses about twice as fast as a column's 16 consecutive rows (tests/bench/pipeline_bench.cpp),
  // with the same rays and so the same returns (but where a ray meets two coincident surfaces at
  // one distance: which of the two). Fewer columns share packets with several rows each.
  // Thread-safe (const): workers cast different columns at once.
  void cast(std::span<const Column> columns) const;
  void cast(int measurement_id, const Pose& world_from_sensor, std::span<IdealReturn> out) const;
  static constexpr size_t kGroupColumns = RayStrip::kColumns;
  float max_range_m() const { return max_range_m_; }

  // What a hit needs from its material, by geomID: copied from the scene once, so a hit reads a
  // flat array instead of calling across modules for every pixel.
  struct SurfaceOptics {
    float reflectivity;
    float specular;
    uint8_t retroreflective;
  };

 private:
  const Scene& scene_;
  const BeamGeometry& geometry_;
  float max_range_m_;
  std::vector<SurfaceOptics> optics_;
  std::vector<TriangleMesh> meshes_;  // by geomID: hits are measured on their triangle (read_hits)

  void cast_group(std::span<const Column> group) const;  // at most kGroupColumns
};

// Whether two neighbouring beams' ideal ranges (0: no hit) lie on different surfaces: one hits and
// the other does not, or both hit farther apart than max(0.3 m, 5 % of the farther range).
bool depth_step(float a, float b);

// Sets IdealReturn::edge from the vertical neighbours in a column: 1 where a neighbour's range
// differs by a depth step (> max(0.3 m, 5 % of the farther range)) or only one of the two hit.
void mark_vertical_edges(std::span<IdealReturn> column);

// Sets IdealReturn::retro_rows and retro_range_m of every pixel that is not itself
// retroreflective from the nearest retroreflective hit within kRetroReachRows rows of the column
// (the upper one on a tie).
void mark_retro_neighbours(std::span<IdealReturn> column);

// A pixel's neighbour as the footprint model sees it (E6).
struct Neighbour {
  const IdealReturn* ideal = nullptr;  // null: none (the frame's end, a column not cast)
  float spacing_rad = 0.0f;            // angle between the two beams' axes
};

// Sets pixel's partner_* fields from its neighbours: the one hit across the largest depth step
// (the step of mark_vertical_edges, and more than twice the range change the pixel's own surface
// makes over the spacing at its incidence), or none. A miss on either side is no partner: a
// footprint straddling the sky loses part of its light but keeps its range.
void choose_edge_partner(IdealReturn& pixel, std::span<const Neighbour> neighbours);

// choose_edge_partner for every pixel of column m from its rows above and below and the same row
// in the adjacent columns (`left` = m - 1, `right` = m + 1; empty when not cast).
void find_edge_partners(std::span<IdealReturn> column, std::span<const IdealReturn> left,
                        std::span<const IdealReturn> right, const BeamGeometry& geometry);

}  // namespace lidartwin
