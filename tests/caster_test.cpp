// BeamGeometry against an independent copy of the SDK's XYZ formula (protocol doc 7.1), the
// conventions of 7.2, and ColumnCaster on a small known scene.
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <span>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/caster/column_caster.h"
#include "lidartwin/scene/scene.h"
#include "support/test_scene.h"

namespace lidartwin {
namespace {

const std::filesystem::path kSample =
    LIDARTWIN_TEST_DATA "/ouster-samples/OS-1-128_767798045_1024x10_20230712_120049.json";

// The real OS-1-128 metadata read directly (nested FW 3.x keys), so this test does not depend on
// the metadata module.
BeamIntrinsics sample_beams() {
  std::ifstream in(kSample);
  const nlohmann::json doc = nlohmann::json::parse(in);
  const auto& bi = doc.at("beam_intrinsics");
  BeamIntrinsics beams;
  beams.altitude_deg = bi.at("beam_altitude_angles").get<std::vector<double>>();
  beams.azimuth_deg = bi.at("beam_azimuth_angles").get<std::vector<double>>();
  beams.lidar_origin_to_beam_origin_mm = bi.at("lidar_origin_to_beam_origin_mm").get<double>();
  const auto b = bi.at("beam_to_lidar_transform").get<std::vector<double>>();
  const auto t = doc.at("lidar_intrinsics").at("lidar_to_sensor_transform").get<std::vector<double>>();
  std::copy(b.begin(), b.end(), beams.beam_to_lidar.begin());
  std::copy(t.begin(), t.end(), beams.lidar_to_sensor.begin());
  return beams;
}

// Independent transcription of make_xyz_lut + cartesianT (7.1), written as the SDK writes it:
// per-pixel unit vector and offset in mm, both put through lidar_to_sensor, then scaled by 0.001.
std::array<double, 3> sdk_xyz(const BeamIntrinsics& b, int w, int row, int col, double range_mm) {
  const double pi = std::numbers::pi;
  const double encoder = 2 * pi - col * 2 * pi / w;
  const double azimuth = -b.azimuth_deg[static_cast<size_t>(row)] * pi / 180.0;
  const double altitude = b.altitude_deg[static_cast<size_t>(row)] * pi / 180.0;
  const auto& B = b.beam_to_lidar;
  const double n = B[11] == 0 ? B[3] : std::hypot(B[3], B[11]);
  const double ux = std::cos(encoder + azimuth) * std::cos(altitude);
  const double uy = std::sin(encoder + azimuth) * std::cos(altitude);
  const double uz = std::sin(altitude);
  const double ox = B[3] * std::cos(encoder) - n * ux;
  const double oy = B[3] * std::sin(encoder) - n * uy;
  const double oz = B[11] - n * uz;
  const auto& T = b.lidar_to_sensor;
  std::array<double, 3> p{};
  for (int i = 0; i < 3; ++i) {
    const double u = T[4 * i] * ux + T[4 * i + 1] * uy + T[4 * i + 2] * uz;
    const double o = T[4 * i] * ox + T[4 * i + 1] * oy + T[4 * i + 2] * oz + T[4 * i + 3];
    p[static_cast<size_t>(i)] = range_mm * 0.001 * u + 0.001 * o;
  }
  return p;
}

double distance(const Eigen::Vector3d& a, const std::array<double, 3>& b) {
  return std::sqrt((a.x() - b[0]) * (a.x() - b[0]) + (a.y() - b[1]) * (a.y() - b[1]) + (a.z() - b[2]) * (a.z() - b[2]));
}

TEST(BeamGeometry, PointMatchesTheSdkFormulaForEveryPixel) {
  const BeamIntrinsics beams = sample_beams();
  ASSERT_EQ(beams.pixels_per_column(), 128);
  const BeamGeometry geometry(beams, 1024);
  double worst = 0;
  for (int m = 0; m < 1024; ++m) {
    for (int r = 0; r < 128; ++r) {
      for (double range_mm : {250.0, 7531.0, 120000.0}) {
        worst = std::max(worst, distance(geometry.point(r, m, range_mm), sdk_xyz(beams, 1024, r, m, range_mm)));
      }
    }
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_EQ(geometry.point(5, 5, 0.0), Eigen::Vector3d::Zero());
}

// The ray's point at a range s is where the SDK puts range s: casting and reprojecting round-trip.
TEST(BeamGeometry, RaysRoundTripThroughTheSdkFormula) {
  const BeamIntrinsics beams = sample_beams();
  for (int width : {512, 1024, 2048}) {
    const BeamGeometry geometry(beams, width);
    double worst = 0;
    for (int m = 0; m < width; ++m) {
      for (int r = 0; r < 128; ++r) {
        const BeamRay& ray = geometry.ray(r, m);
        EXPECT_NEAR(ray.direction.norm(), 1.0f, 1e-6f);
        for (double s_m : {0.3, 2.0, 9.0}) {  // float rays: 1e-6 m holds to ~10 m (6e-8 relative)
          const Eigen::Vector3d hit = ray.origin_m.cast<double>() + s_m * ray.direction.cast<double>();
          worst = std::max(worst, distance(hit, sdk_xyz(beams, width, r, m, s_m * 1000.0)));
        }
      }
    }
    EXPECT_LT(worst, 1e-6) << "W=" << width;
  }
}

TEST(BeamGeometry, RangeOffsetIsTheBeamOriginDistance) {
  const BeamIntrinsics beams = sample_beams();
  const BeamGeometry geometry(beams, 1024);
  EXPECT_NEAR(geometry.ray(0, 0).range_offset_m, 0.016721f, 1e-7f);
  // The physical beam origin (range n) lies B[0][3] from the spin axis, at the lidar origin height.
  for (int m : {0, 100, 700}) {
    const auto p = sdk_xyz(beams, 1024, 17, m, 16.721);
    EXPECT_NEAR(std::hypot(p[0], p[1]), 0.016721, 1e-9);
    EXPECT_NEAR(p[2], 0.038195, 1e-9);
  }
}

// 7.2 conventions with the default OS lidar_to_sensor (180 degrees about z) and zero offsets.
TEST(BeamGeometry, FollowsTheSensorFrameConventions) {
  BeamIntrinsics beams;
  beams.altitude_deg = {10.0, 0.0, -10.0};
  beams.azimuth_deg = {0.0, 0.0, 0.0};
  const int w = 1024;
  const BeamGeometry geometry(beams, w);
  const auto dir = [&](int m) { return geometry.ray(1, m).direction; };
  EXPECT_NEAR((dir(0) - Eigen::Vector3f(-1, 0, 0)).norm(), 0.0f, 1e-6f);  // toward the connector
  EXPECT_NEAR((dir(w / 4) - Eigen::Vector3f(0, 1, 0)).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((dir(w / 2) - Eigen::Vector3f(1, 0, 0)).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((dir(3 * w / 4) - Eigen::Vector3f(0, -1, 0)).norm(), 0.0f, 1e-6f);
  EXPECT_GT(geometry.ray(0, 0).direction.z(), geometry.ray(1, 0).direction.z());  // row 0 highest
  const BeamGeometry real(sample_beams(), w);
  for (int r = 1; r < real.rows(); ++r) EXPECT_GT(real.ray(r - 1, 0).direction.z(), real.ray(r, 0).direction.z());
}

TEST(ColumnCaster, MarksVerticalEdges) {
  std::vector<IdealReturn> column(6);
  const float ranges[6] = {10.0f, 10.1f, 10.2f, 20.0f, 20.1f, 0.0f};
  for (size_t i = 0; i < 6; ++i) column[i].range_m = ranges[i];
  mark_vertical_edges(column);
  // A step between rows 2 and 3; rows 4 and 5 differ in hit/miss (a miss beside a hit is an edge too).
  const uint8_t expected[6] = {0, 0, 1, 1, 1, 1};
  for (size_t i = 0; i < 6; ++i) EXPECT_EQ(column[i].edge, expected[i]) << "row " << i;
}

// E8's input: the nearest retroreflective hit within 8 rows of the same column, the upper one on
// a tie; a retroreflector itself and pixels farther away get none.
TEST(ColumnCaster, MarksTheNearestRetroreflectorInTheColumn) {
  std::vector<IdealReturn> column(40);
  for (size_t i = 0; i < column.size(); ++i) column[i].range_m = 20.0f;
  column[10].retroreflective = column[14].retroreflective = 1;
  column[10].range_m = 7.0f;
  column[14].range_m = 9.0f;
  column[39].retro_rows = 5;  // stale, from an earlier column: cleared
  mark_retro_neighbours(column);
  const auto expect = [&](size_t row, int rows, float range) {
    EXPECT_EQ(column[row].retro_rows, rows) << "row " << row;
    EXPECT_EQ(column[row].retro_range_m, range) << "row " << row;
  };
  expect(2, 8, 7.0f);
  expect(1, 0, 0.0f);  // 9 rows above the first
  expect(9, 1, 7.0f);
  expect(10, 0, 0.0f);  // a retroreflector
  expect(12, 2, 7.0f);  // midway: the upper one
  expect(13, 1, 9.0f);
  expect(22, 8, 9.0f);
  expect(23, 0, 0.0f);
  expect(39, 0, 0.0f);
  std::vector<IdealReturn> plain(8);
  plain[3].retro_rows = 2;
  mark_retro_neighbours(plain);
  EXPECT_EQ(plain[3].retro_rows, 0) << "no retroreflector in the column";
}

TEST(ColumnCaster, EdgePartnersAreTheHitsAcrossTheLargestDepthStep) {
  const BeamIntrinsics beams = sample_beams();
  const BeamGeometry geometry(beams, 1024);
  const auto column_of = [](std::vector<float> ranges) {
    std::vector<IdealReturn> column(128);
    for (size_t i = 0; i < column.size(); ++i) {
      column[i].range_m = i < ranges.size() ? ranges[i] : 30.0f;
      column[i].reflectivity = 0.4f;
      column[i].cos_incidence = 0.5f;
    }
    return column;
  };
  // Rows 0-2 a board at 10 m, row 3 the wall behind at 30 m, row 4 a miss; the column to the
  // right holds a post at 5 m in row 1.
  std::vector<IdealReturn> column = column_of({10.0f, 10.1f, 10.2f, 30.0f, 0.0f});
  std::vector<IdealReturn> right = column_of({10.0f, 5.0f, 10.2f, 30.0f, 0.0f});
  find_edge_partners(column, {}, right, geometry);
  EXPECT_FALSE(column[0].has_partner()) << "10.1 m above is no depth step";
  EXPECT_FLOAT_EQ(column[1].partner_range_m, 5.0f) << "the post beside it";
  EXPECT_FLOAT_EQ(column[1].partner_spacing_rad, geometry.column_spacing_rad(1));
  EXPECT_FLOAT_EQ(column[2].partner_range_m, 30.0f) << "the wall below: a 19.8 m step";
  EXPECT_FLOAT_EQ(column[2].partner_spacing_rad, geometry.row_spacing_rad(2));
  EXPECT_FLOAT_EQ(column[2].partner_reflectance, 0.2f);
  EXPECT_FLOAT_EQ(column[3].partner_range_m, 10.2f) << "the board above; the miss below is no partner";
  EXPECT_FALSE(column[4].has_partner()) << "a miss has no partner";
  // The spacings are the angles between the beams' axes: about 360/1024 degrees between columns;
  // between rows, the altitude step and the rows' azimuth offsets (staggered on this OS-1-128).
  EXPECT_NEAR(static_cast<double>(geometry.column_spacing_rad(64)) * 180 / std::numbers::pi, 360.0 / 1024, 0.01);
  for (const int row : {0, 63, 64, 126}) {
    const auto r = static_cast<size_t>(row);
    const double altitude = std::abs(beams.altitude_deg[r + 1] - beams.altitude_deg[r]);
    const double azimuth = std::abs(beams.azimuth_deg[r + 1] - beams.azimuth_deg[r]);
    const double spacing = static_cast<double>(geometry.row_spacing_rad(row)) * 180 / std::numbers::pi;
    EXPECT_GE(spacing, altitude - 1e-3) << row;
    EXPECT_LE(spacing, std::hypot(altitude, azimuth) + 1e-3) << row;
  }
}

// find_edge_partners chooses for all rows at once with SIMD selects; choose_edge_partner is the
// rule written out. On columns of surfaces at random ranges, incidences and holes (and a column
// shorter than a vector multiple), both choose the same partner, bit for bit.
TEST(ColumnCaster, EdgePartnersOfAColumnAreChooseEdgePartnersRowByRow) {
  const BeamGeometry geometry(sample_beams(), 1024);
  std::mt19937 random(5);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const auto random_column = [&](size_t rows) {
    std::vector<IdealReturn> column(rows);
    float range = 1.0f + 40.0f * unit(random);
    for (auto& pixel : column) {
      const float u = unit(random);
      if (u < 0.1f) range = 1.0f + 40.0f * unit(random);  // a depth step
      pixel.range_m = u > 0.93f ? 0.0f : range * (1.0f + 0.03f * (unit(random) - 0.5f));
      pixel.cos_incidence = unit(random) < 0.1f ? 0.01f : unit(random);
      pixel.reflectivity = unit(random);
    }
    return column;
  };
  int partners = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const size_t rows = trial % 5 == 0 ? 37 : 128;
    const std::vector<IdealReturn> left = random_column(rows), right = random_column(rows);
    std::vector<IdealReturn> column = random_column(rows);
    const std::vector<IdealReturn> before = column;
    find_edge_partners(column, left, trial % 3 == 0 ? std::span<const IdealReturn>() : right, geometry);
    for (size_t r = 0; r < rows; ++r) {
      const int row = static_cast<int>(r);
      IdealReturn expected = before[r];
      const std::array<Neighbour, 4> neighbours{{
          {r > 0 ? &before[r - 1] : nullptr, r > 0 ? geometry.row_spacing_rad(row - 1) : 0.0f},
          {r + 1 < rows ? &before[r + 1] : nullptr, r + 1 < rows ? geometry.row_spacing_rad(row) : 0.0f},
          {&left[r], geometry.column_spacing_rad(row)},
          {trial % 3 == 0 ? nullptr : &right[r], geometry.column_spacing_rad(row)},
      }};
      choose_edge_partner(expected, neighbours);
      ASSERT_EQ(column[r].partner_range_m, expected.partner_range_m) << "trial " << trial << " row " << r;
      ASSERT_EQ(column[r].partner_reflectance, expected.partner_reflectance) << "trial " << trial << " row " << r;
      ASSERT_EQ(column[r].partner_spacing_rad, expected.partner_spacing_rad) << "trial " << trial << " row " << r;
      partners += expected.has_partner();
    }
  }
  EXPECT_GT(partners, 1000) << "the columns have edges to choose partners at";
}

class ColumnCasterScene : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lidartwin_caster_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    // A wall at world x = 5 facing the sensor, 0.2 reflective; nothing elsewhere.
    test::write_glb(dir_ / "wall.glb",
                    {test::quad("wall", {5, -50, -50}, {5, 50, -50}, {5, 50, 50}, {5, -50, 50}, 0.2f)});
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(ColumnCasterScene, HitsTheWallWhereTheSdkPutsTheRange) {
  const Scene scene = Scene::load(dir_ / "wall.glb");
  const BeamIntrinsics beams = sample_beams();
  const BeamGeometry geometry(beams, 1024);
  const ColumnCaster caster(scene, geometry, 100.0f);
  Pose pose;  // the sensor 1 m up, yawed 30 degrees
  pose.translation = {0, 0, 1};
  pose.rotation = Eigen::AngleAxisd(std::numbers::pi / 6, Eigen::Vector3d::UnitZ());
  std::vector<IdealReturn> column(128);
  int hits = 0;
  for (int m = 0; m < 1024; m += 7) {
    caster.cast(m, pose, column);
    for (int r = 0; r < 128; ++r) {
      const IdealReturn& ideal = column[static_cast<size_t>(r)];
      const auto p_sensor = sdk_xyz(beams, 1024, r, m, static_cast<double>(ideal.range_m) * 1000.0);
      const Eigen::Vector3d p = pose * Eigen::Vector3d(p_sensor[0], p_sensor[1], p_sensor[2]);
      const Eigen::Vector3d d = pose.rotation * geometry.ray(r, m).direction.cast<double>();
      if (!ideal.hit()) {
        EXPECT_TRUE(d.x() <= 0.1 || ideal.range_m > 95.0f) << "missed the wall at m=" << m << " r=" << r;
        continue;
      }
      ++hits;
      EXPECT_NEAR(p.x(), 5.0, 2e-5) << "m=" << m << " r=" << r;
      EXPECT_NEAR(static_cast<double>(ideal.cos_incidence), std::abs(d.x()), 1e-5);
      EXPECT_FLOAT_EQ(ideal.reflectivity, 0.2f);
      EXPECT_LE(ideal.range_m, 100.0f);
    }
  }
  EXPECT_GT(hits, 1000);
}

// Columns cast together share packets (a row of 16 neighbours, or several rows of fewer columns);
// the returns must be those of each column cast alone, whatever the group: 16 neighbours, fewer,
// columns apart, each from its own pose. On the plant, where rays hit many surfaces at all depths.
TEST(ColumnCasterPlant, ColumnsCastTogetherReturnWhatEachReturnsAlone) {
  const Scene scene = Scene::load(std::filesystem::path(LIDARTWIN_SOURCE_DIR) / "scenes/plant.glb");
  const BeamIntrinsics beams = sample_beams();
  const BeamGeometry geometry(beams, 2048);
  const ColumnCaster caster(scene, geometry, 100.0f);
  // 16 neighbours as the renderer's blocks (one strip per packet), then a mixed group of 11.
  std::vector<int> ids;
  for (int m = 160; m < 176; ++m) ids.push_back(m);
  ids.insert(ids.end(), {100, 101, 102, 103, 104, 105, 106, 900, 901, 1500, 7});
  std::vector<std::vector<IdealReturn>> together(ids.size(), std::vector<IdealReturn>(128));
  std::vector<Pose> poses(ids.size());
  std::vector<ColumnCaster::Column> columns;
  for (size_t i = 0; i < ids.size(); ++i) {
    // At head height under the racks, a little further along for each column.
    poses[i].translation = {15.0 + 0.01 * static_cast<double>(i), 9.0, 1.7};
    poses[i].rotation = Eigen::AngleAxisd(0.02 * static_cast<double>(i), Eigen::Vector3d::UnitZ());
    columns.push_back({ids[i], &poses[i], together[i]});
  }
  caster.cast(columns);
  std::vector<IdealReturn> alone(128);
  int hits = 0;
  for (size_t i = 0; i < ids.size(); ++i) {
    caster.cast(ids[i], poses[i], alone);
    for (size_t r = 0; r < 128; ++r) {
      const IdealReturn& a = alone[r];
      const IdealReturn& t = together[i][r];
      hits += a.hit();
      EXPECT_EQ(t.range_m, a.range_m) << "column " << ids[i] << " row " << r;
      EXPECT_EQ(t.cos_incidence, a.cos_incidence) << "column " << ids[i] << " row " << r;
      EXPECT_EQ(t.material_id, a.material_id) << "column " << ids[i] << " row " << r;
      EXPECT_EQ(t.reflectivity, a.reflectivity) << "column " << ids[i] << " row " << r;
      EXPECT_EQ(t.beam, r) << "column " << ids[i];
      EXPECT_EQ(t.edge, a.edge) << "column " << ids[i] << " row " << r;
      EXPECT_EQ(t.retro_rows, a.retro_rows) << "column " << ids[i] << " row " << r;
    }
  }
  EXPECT_GT(hits, 1000) << "the test needs returns to compare";
}

}  // namespace
}  // namespace lidartwin
