#include "lidartwin/frame/imu_model.h"

#include <numbers>

#include <Eigen/Geometry>

namespace lidartwin {

namespace {
// A real IMU stamps accelerometer and gyro reads a little before the packet's sys_ts (5.1: about
// 0.2 ms apart in real captures).
constexpr uint64_t kAccelLeadNs = 400'000;
constexpr uint64_t kGyroLeadNs = 200'000;

std::array<float, 3> to_floats(const Eigen::Vector3d& v) {
  return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

// Body-frame angular velocity from the rotation step world_from_sensor(t-h) -> (t+h).
Eigen::Vector3d angular_velocity(const Pose& before, const Pose& after, double interval_s) {
  const Eigen::AngleAxisd delta(before.rotation.conjugate() * after.rotation);
  return delta.axis() * (delta.angle() / interval_s);
}
}  // namespace

ImuSample imu_sample(const PoseSource& poses, double time_s, uint64_t timestamp_ns, double step_s) {
  const Pose before = poses.at(time_s - step_s);
  const Pose now = poses.at(time_s);
  const Pose after = poses.at(time_s + step_s);

  // Specific force: what an accelerometer reads is acceleration minus gravity (world Z up).
  const Eigen::Vector3d acceleration_world =
      (after.translation - 2.0 * now.translation + before.translation) / (step_s * step_s);
  const Eigen::Vector3d specific_force_world = acceleration_world + Eigen::Vector3d(0.0, 0.0, kStandardGravity);
  const Eigen::Vector3d accel_sensor = now.rotation.conjugate() * specific_force_world;
  const Eigen::Vector3d gyro_sensor = angular_velocity(before, after, 2.0 * step_s);

  ImuSample sample;
  sample.sys_ts_ns = timestamp_ns;
  sample.accel_ts_ns = timestamp_ns > kAccelLeadNs ? timestamp_ns - kAccelLeadNs : timestamp_ns;
  sample.gyro_ts_ns = timestamp_ns > kGyroLeadNs ? timestamp_ns - kGyroLeadNs : timestamp_ns;
  sample.accel_g = to_floats(accel_sensor / kStandardGravity);
  sample.gyro_deg_s = to_floats(gyro_sensor * (180.0 / std::numbers::pi));
  return sample;
}

}  // namespace lidartwin
