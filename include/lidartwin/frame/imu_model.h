#pragma once
// What the IMU measures along the sensor's motion (protocol doc 5.1): specific force and angular
// rate at the IMU's own position and in its own axes (imu_to_sensor_transform), and the errors of a
// MEMS IMU on top (ImuNoise: white noise, bias random walk, g-sensitivity), drawn from the seed so
// that the same seed gives the same packets.
#include <cstdint>
#include <mutex>

#include <Eigen/Core>

#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/beam_intrinsics.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin {

inline constexpr double kStandardGravity = 9.80665;  // m/s^2, the SDK's g (5.1)

struct ImuReading {
  Eigen::Vector3d specific_force = Eigen::Vector3d::Zero();  // m/s^2, IMU frame
  Eigen::Vector3d angular_rate = Eigen::Vector3d::Zero();    // rad/s, IMU frame
};

// imu_to_sensor_transform (mm) as a pose: sensor_from_imu in metres.
Pose sensor_from_imu(const Mat4& imu_to_sensor);

// What an exact IMU at sensor_from_imu reads at pose time time_s. Motion comes from central
// differences over +-step_s of the IMU's own pose, so a lever arm's centripetal force is in it; at
// rest it reads +g along the world's up.
ImuReading imu_reading(const PoseSource& poses, double time_s, const Pose& sensor_from_imu = {}, double step_s = 0.02);
// In the packet's units (g, deg/s), stamped timestamp_ns on the lidar's clock.
ImuSample to_imu_sample(const ImuReading& reading, uint64_t timestamp_ns);
inline ImuSample imu_sample(const PoseSource& poses, double time_s, uint64_t timestamp_ns, double step_s = 0.02) {
  return to_imu_sample(imu_reading(poses, time_s, {}, step_s), timestamp_ns);
}

// A MEMS IMU's errors on sample i of a stream sampled every period_s, in Kalibr's discrete form:
// white noise sigma = density / sqrt(period), each bias a random walk b(i) = b(i-1) + walk *
// sqrt(period) * n(i) from b(0) = 0, and the gyro reading g-sensitivity times the specific force.
// Every draw is a pure function of (seed, i), so output does not depend on who asks when; asking
// in order is O(1) per sample, jumping back recomputes the walk from the start.
class ImuErrors {
 public:
  ImuErrors(const ImuNoise& noise, uint64_t seed, double period_s);
  ImuReading apply(uint64_t sample, const ImuReading& exact) const;

 private:
  struct Biases {
    Eigen::Vector3d accel = Eigen::Vector3d::Zero();
    Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  };
  Biases biases_at(uint64_t sample) const;  // mutex_ held

  ImuNoise noise_;
  uint64_t seed_;
  double period_s_;
  mutable std::mutex mutex_;
  mutable uint64_t cached_sample_ = 0;
  mutable Biases cached_;
};

}  // namespace lidartwin
