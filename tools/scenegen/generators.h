#pragma once
// The committed scenes and trajectories (README "Scenes and materials").
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "glb_writer.h"

namespace lidartwin::scenegen {

// world_from_sensor of an Ouster sensor frame (x forward, z up) at a time.
struct StampedPose {
  double time_s = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

GlbWriter build_plant();
GlbWriter build_calibration_hall();
GlbWriter build_yard();

// The closed drone loop around the plant (plant_flight.cpp).
std::vector<StampedPose> plant_inspection_flight();
// The SLAM lap over the yard, from rest on the pad to a hover over it (yard_flight.cpp).
std::vector<StampedPose> yard_flight();
// The static recording pose in the calibration hall: on the centre line, 4 m above the floor,
// looking down the hall (+x).
StampedPose calibration_hall_pose();

// TUM "t x y z qx qy qz qw" with a '#' header line.
void write_tum(const std::filesystem::path& path, const std::vector<StampedPose>& poses, const std::string& comment);

}  // namespace lidartwin::scenegen
