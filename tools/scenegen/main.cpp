// lidartwin-scenegen: writes the committed scenes and trajectories (README "Scenes and materials").
//   lidartwin-scenegen [output-directory]      (default: the source tree's scenes/)
#include <cstdio>
#include <exception>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "flight_check.h"
#include "generators.h"

namespace fs = std::filesystem;
using namespace lidartwin::scenegen;

namespace {

void report(const fs::path& path, size_t triangles) {
  std::printf("%s: %zu triangles, %ju bytes\n", path.c_str(), triangles, static_cast<uintmax_t>(fs::file_size(path)));
}

// A drone needs room: refuse a path that passes within 3 m of anything.
Clearance checked_clearance(const char* name, const fs::path& scene, const std::vector<StampedPose>& flight) {
  const Clearance clearance = min_clearance(scene, flight, 10.0);
  if (clearance.distance_m < 3.0) {
    const Eigen::Vector3d& p = clearance.where;
    throw std::runtime_error(std::string(name) + ": the path passes " + std::to_string(clearance.distance_m) +
                             " m from the scene at (" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ", " +
                             std::to_string(p.z()) + ")");
  }
  return clearance;
}

void write_plant(const fs::path& dir) {
  const GlbWriter plant = build_plant();
  plant.write(dir / "plant.glb");
  report(dir / "plant.glb", plant.triangle_count());
  const std::vector<StampedPose> flight = plant_inspection_flight();
  const Clearance clearance = checked_clearance("plant_inspection", dir / "plant.glb", flight);
  write_tum(dir / "plant_inspection.tum", flight,
            "lidartwin-scenegen: inspection lap around scenes/plant.glb, world_from_sensor (Ouster sensor frame), "
            "4 m/s, 20 Hz, closed");
  std::printf("%s: %zu poses over %.1f s, clearance >= %.1f m\n", (dir / "plant_inspection.tum").c_str(), flight.size(),
              flight.back().time_s, clearance.distance_m);
}

void write_hall(const fs::path& dir) {
  const GlbWriter hall = build_calibration_hall();
  hall.write(dir / "calibration_hall.glb");
  report(dir / "calibration_hall.glb", hall.triangle_count());
  write_tum(dir / "calibration_hall_static.tum", {calibration_hall_pose()},
            "lidartwin-scenegen: static recording pose in scenes/calibration_hall.glb, world_from_sensor");
}

void write_yard(const fs::path& dir) {
  const GlbWriter yard = build_yard();
  yard.write(dir / "yard.glb");
  report(dir / "yard.glb", yard.triangle_count());
  const std::vector<StampedPose> flight = yard_flight();
  // On the pad the drone is near the ground by design: check the clearance once it is airborne.
  const std::vector<StampedPose> airborne(flight.begin() + 100, flight.end() - 100);
  const Clearance clearance = checked_clearance("yard_flight", dir / "yard.glb", airborne);
  write_tum(dir / "yard_flight.tum", flight,
            "lidartwin-scenegen: SLAM lap over scenes/yard.glb from rest on the pad, world_from_sensor (Ouster "
            "sensor frame), 4 m/s at 5 m, 20 Hz");
  std::printf("%s: %zu poses over %.1f s, clearance >= %.1f m when airborne\n", (dir / "yard_flight.tum").c_str(),
              flight.size(), flight.back().time_s, clearance.distance_m);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 2 || (argc == 2 && argv[1][0] == '-')) {
    std::fprintf(stderr, "usage: lidartwin-scenegen [output-directory]   (default: %s/scenes)\n", LIDARTWIN_SOURCE_DIR);
    return 2;
  }
  const fs::path dir = argc == 2 ? fs::path(argv[1]) : fs::path(LIDARTWIN_SOURCE_DIR) / "scenes";
  try {
    fs::create_directories(dir);
    write_hall(dir);
    write_plant(dir);
    write_yard(dir);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lidartwin-scenegen: %s\n", e.what());
    return 1;
  }
  return 0;
}
