// The calibration hall (scenes/calibration_hall.glb): a 230 m × 40 m × 14 m hall with flat target
// boards seen from calibration_hall_pose() at ranges 1–100 m, reflectivities 0.05–0.9 plus a
// retroreflector, and incidence angles 0–75°. Boards are laid out so that none hides another from
// the pose: their angular extents (azimuth × elevation) never overlap.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "generators.h"

namespace lidartwin::scenegen {
namespace {

using V = Eigen::Vector3f;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kHalfLength = 115.0, kHalfWidth = 20.0, kHeight = 14.0, kSensorHeight = 4.0;

struct Target {
  double range_m;  // sensor to board centre
  double reflectivity;
  double incidence_deg;  // board normal turned away from the line of sight
  double elevation_deg;  // row: 0 at sensor height, ±11° for the ladders
  bool retro = false;
  double azimuth_deg = 0.0;  // chosen by place()
};

// Main series at the datasheet's 10 % reflectivity (paper Table I), plus bright boards, a
// reflectivity ladder (row +11°), incidence ladders and retroreflective panels.
std::vector<Target> target_list() {
  std::vector<Target> t;
  for (double r : {1.0,  1.5,  2.0,  3.0,  4.0,  5.0,  6.0,  8.0,  10.0, 12.0, 15.0, 20.0,
                   25.0, 30.0, 35.0, 40.0, 45.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0}) {
    t.push_back({r, 0.10, 0.0, 0.0});
  }
  for (double r : {2.5, 7.0, 28.0, 55.0, 85.0}) t.push_back({r, 0.80, 0.0, 0.0});
  for (double rho : {0.05, 0.2, 0.35, 0.5, 0.65, 0.9}) t.push_back({10.0, rho, 0.0, 11.0});
  t.push_back({10.0, 0.9, 0.0, 11.0, true});
  for (double inc : {0.0, 15.0, 30.0, 45.0, 60.0, 75.0}) t.push_back({6.0, 0.5, inc, -11.0});
  for (double inc : {30.0, 60.0, 75.0}) t.push_back({25.0, 0.5, inc, 0.0});
  t.push_back({40.0, 0.9, 0.0, 0.0, true});
  return t;
}

// Board size: 3° × 12° far away (4 columns × 4 beams of the 512-column paper OS0-32), a
// fixed-plus-proportional size near by.
Eigen::Vector2d board_size(double range_m) {
  if (range_m >= 16.0) return {0.052 * range_m, 0.21 * range_m};
  return {0.3 + 0.08 * range_m, 0.3 + 0.1 * range_m};
}

struct Extent {
  double az_lo, az_hi, el_lo, el_hi;  // degrees, with a 1° margin
};

Extent extent_of(const Target& t) {
  const Eigen::Vector2d size = board_size(t.range_m);
  const double half_az = std::atan(size.x() * std::cos(t.incidence_deg * kDeg) / 2 / t.range_m) / kDeg + 1.0;
  const double half_el = std::atan(size.y() / 2 / t.range_m) / kDeg + 1.0;
  return {t.azimuth_deg - half_az, t.azimuth_deg + half_az, t.elevation_deg - half_el, t.elevation_deg + half_el};
}

bool overlaps(const Extent& a, const Extent& b) {
  const auto wrap = [](double d) { return std::remainder(d, 360.0); };
  const double centre_gap = std::abs(wrap((a.az_lo + a.az_hi - b.az_lo - b.az_hi) / 2));
  const bool az = centre_gap < (a.az_hi - a.az_lo + b.az_hi - b.az_lo) / 2;
  return az && a.el_lo < b.el_hi && b.el_lo < a.el_hi;
}

bool inside_hall(const Target& t) {
  const double w = board_size(t.range_m).x();
  const double ground = t.range_m * std::cos(t.elevation_deg * kDeg);
  return std::abs(ground * std::sin(t.azimuth_deg * kDeg)) + w / 2 <= kHalfWidth - 1.0 &&
         std::abs(ground * std::cos(t.azimuth_deg * kDeg)) + w / 2 <= kHalfLength - 2.0;
}

// Azimuths in 0.25° steps, nearest to `home` (or home + 180°) first.
std::vector<double> candidate_azimuths(double home) {
  std::vector<double> out;
  for (int k = 0; k <= 360; ++k) {
    for (const double base : {home, home + 180.0}) {
      for (const double sign : {1.0, -1.0}) out.push_back(std::remainder(base + sign * 0.25 * k, 360.0));
    }
  }
  return out;
}

// Greedy, farthest board first: each takes the free azimuth nearest the hall's axis (boards from
// 16 m) or its sides (nearer boards, which would otherwise hide a wide sector).
void place(std::vector<Target>& targets) {
  std::stable_sort(targets.begin(), targets.end(),
                   [](const Target& a, const Target& b) { return a.range_m > b.range_m; });
  std::vector<Extent> placed;
  for (Target& t : targets) {
    const auto fits = [&](double azimuth) {
      t.azimuth_deg = azimuth;
      const Extent e = extent_of(t);
      return inside_hall(t) &&
             std::none_of(placed.begin(), placed.end(), [&](const Extent& p) { return overlaps(p, e); });
    };
    const std::vector<double> candidates = candidate_azimuths(t.range_m >= 16.0 ? 0.0 : 90.0);
    const auto it = std::find_if(candidates.begin(), candidates.end(), fits);
    if (it == candidates.end()) {
      throw std::runtime_error("calibration hall: no free place for the board at " + std::to_string(t.range_m) + " m");
    }
    t.azimuth_deg = *it;
    placed.push_back(extent_of(t));
  }
}

// A 3 cm board whose front face passes through the point at its nominal range, facing the sensor,
// turned by its incidence angle about its own vertical axis; far boards are clipped 0.1 m above
// the floor and 0.2 m below the ceiling.
Mesh board(const Target& t, const V& sensor) {
  const Eigen::Vector2d size = board_size(t.range_m);
  const V dir(static_cast<float>(std::cos(t.elevation_deg * kDeg) * std::cos(t.azimuth_deg * kDeg)),
              static_cast<float>(std::cos(t.elevation_deg * kDeg) * std::sin(t.azimuth_deg * kDeg)),
              static_cast<float>(std::sin(t.elevation_deg * kDeg)));
  const V centre = sensor + static_cast<float>(t.range_m) * dir;
  const V up = (V::UnitZ() - V::UnitZ().dot(dir) * dir).normalized();
  const Eigen::AngleAxisf turn(static_cast<float>(t.incidence_deg * kDeg), up);
  const V normal = turn * -dir, right = up.cross(normal);
  Eigen::Matrix3f axes;
  axes << right, up, normal;
  const float half_h = static_cast<float>(size.y() / 2);
  const float down = std::min(half_h, centre.z() - 0.1f);
  const float up_extent = std::min(half_h, static_cast<float>(kHeight) - 0.2f - centre.z());
  Mesh mesh;
  mesh.append(
      box({-static_cast<float>(size.x() / 2), -down, -0.03f}, {static_cast<float>(size.x() / 2), up_extent, 0.0f}),
      Eigen::Translation3f(centre) * Eigen::Affine3f(axes));
  return mesh;
}

std::string board_name(const Target& t) {
  char name[128];
  std::snprintf(name, sizeof name, "target_r%06.2f_az%+07.2f_el%+06.2f_rho%.2f_inc%02.0f%s", t.range_m, t.azimuth_deg,
                t.elevation_deg, t.reflectivity, t.incidence_deg, t.retro ? "_retro" : "");
  return name;
}

int hall_shell(GlbWriter& out) {
  const int floor = out.add_material({"floor_concrete", 0.3, false, 0.0, {0.6, 0.6, 0.58}});
  const int wall = out.add_material({"wall_paint", 0.6, false, 0.0, {0.85, 0.85, 0.8}});
  const int ceiling = out.add_material({"ceiling_panels", 0.7, false, 0.0, {0.9, 0.9, 0.9}});
  const int pillar = out.add_material({"pillar_steel_paint", 0.4, false, 0.1, {0.3, 0.35, 0.5}});
  const float l = static_cast<float>(kHalfLength), w = static_cast<float>(kHalfWidth), h = static_cast<float>(kHeight);
  Mesh walls, pillars;
  walls.append(box({-l - 0.3f, -w - 0.3f, -0.3f}, {-l, w + 0.3f, h + 0.3f}));
  walls.append(box({l, -w - 0.3f, -0.3f}, {l + 0.3f, w + 0.3f, h + 0.3f}));
  walls.append(box({-l, -w - 0.3f, -0.3f}, {l, -w, h + 0.3f}));
  walls.append(box({-l, w, -0.3f}, {l, w + 0.3f, h + 0.3f}));
  for (float x = -l + 5.0f; x < l; x += 10.0f) {
    for (const float y : {-w + 0.3f, w - 0.3f}) pillars.append(box_at({x, y, h / 2}, {0.6f, 0.6f, h}));
  }
  return out.add_mesh("hall", {{floor, box({-l, -w, -0.3f}, {l, w, 0.0f})},
                               {ceiling, box({-l, -w, h}, {l, w, h + 0.3f})},
                               {wall, walls},
                               {pillar, pillars}});
}

}  // namespace

StampedPose calibration_hall_pose() { return {0.0, {0.0, 0.0, kSensorHeight}, Eigen::Quaterniond::Identity()}; }

GlbWriter build_calibration_hall() {
  GlbWriter out;
  out.add_instance(hall_shell(out), "hall", Eigen::Vector3d::Zero());
  std::vector<Target> targets = target_list();
  place(targets);
  const V sensor = calibration_hall_pose().position.cast<float>();
  std::vector<std::pair<int, Mesh>> boards;
  for (const Target& t : targets) {
    const double grey = std::min(1.0, t.reflectivity);
    const int material = out.add_material({board_name(t), t.reflectivity, t.retro, 0.0, {grey, grey, grey}});
    boards.emplace_back(material, board(t, sensor));
  }
  out.add_instance(out.add_mesh("targets", boards), "targets", Eigen::Vector3d::Zero());
  return out;
}

}  // namespace lidartwin::scenegen
