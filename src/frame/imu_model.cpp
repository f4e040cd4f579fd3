#include "lidartwin/frame/imu_model.h"

#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "lidartwin/random/counter_rng.h"

namespace lidartwin {

namespace {
// A real IMU stamps accelerometer and gyro reads a little before the packet's sys_ts (5.1: about
// 0.2 ms apart in real captures).
constexpr uint64_t kAccelLeadNs = 400'000;
constexpr uint64_t kGyroLeadNs = 200'000;
// The IMU's random stream: its own "effect" id, and a column no frame has.
constexpr uint32_t kImuStream = 0x494D55;  // "IMU"
constexpr uint32_t kImuColumn = 0xFFFF'FFFF;

std::array<float, 3> to_floats(const Eigen::Vector3d& v) {
  return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

// Body-frame angular velocity from the rotation step world_from_imu(t-h) -> (t+h).
Eigen::Vector3d angular_velocity(const Pose& before, const Pose& after, double interval_s) {
  const Eigen::AngleAxisd delta(before.rotation.conjugate() * after.rotation);
  return delta.axis() * (delta.angle() / interval_s);
}

RandomStream imu_stream(uint64_t seed, uint64_t sample) { return {seed, PixelKey{sample, kImuColumn, 0}, kImuStream}; }

// Standard normals of pairs [first, first + 3).
Eigen::Vector3d normals(const RandomStream& stream, uint32_t first) {
  return {stream.normal(first), stream.normal(first + 1), stream.normal(first + 2)};
}
}  // namespace

Pose sensor_from_imu(const Mat4& m) {
  Eigen::Matrix3d rotation;
  rotation << m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10];
  Pose pose;
  pose.rotation = Eigen::Quaterniond(rotation).normalized();
  pose.translation = 1e-3 * Eigen::Vector3d(m[3], m[7], m[11]);
  return pose;
}

ImuReading imu_reading(const PoseSource& poses, double time_s, const Pose& sensor_from_imu, double step_s) {
  const Pose before = poses.at(time_s - step_s) * sensor_from_imu;
  const Pose now = poses.at(time_s) * sensor_from_imu;
  const Pose after = poses.at(time_s + step_s) * sensor_from_imu;
  // Specific force: what an accelerometer reads is acceleration minus gravity (world Z up).
  const Eigen::Vector3d acceleration_world =
      (after.translation - 2.0 * now.translation + before.translation) / (step_s * step_s);
  const Eigen::Vector3d specific_force_world = acceleration_world + Eigen::Vector3d(0.0, 0.0, kStandardGravity);
  return {now.rotation.conjugate() * specific_force_world, angular_velocity(before, after, 2.0 * step_s)};
}

ImuSample to_imu_sample(const ImuReading& reading, uint64_t timestamp_ns) {
  ImuSample sample;
  sample.sys_ts_ns = timestamp_ns;
  sample.accel_ts_ns = timestamp_ns > kAccelLeadNs ? timestamp_ns - kAccelLeadNs : timestamp_ns;
  sample.gyro_ts_ns = timestamp_ns > kGyroLeadNs ? timestamp_ns - kGyroLeadNs : timestamp_ns;
  sample.accel_g = to_floats(reading.specific_force / kStandardGravity);
  sample.gyro_deg_s = to_floats(reading.angular_rate * (180.0 / std::numbers::pi));
  return sample;
}

ImuErrors::ImuErrors(const ImuNoise& noise, uint64_t seed, double period_s)
    : noise_(noise), seed_(seed), period_s_(period_s) {}

ImuErrors::Biases ImuErrors::biases_at(uint64_t sample) const {
  if (sample < cached_sample_) {
    cached_sample_ = 0;
    cached_ = {};
  }
  const double step = std::sqrt(period_s_);
  while (cached_sample_ < sample) {
    ++cached_sample_;
    const RandomStream stream = imu_stream(seed_, cached_sample_);
    cached_.accel += noise_.accelerometer_random_walk * step * normals(stream, 6);
    cached_.gyro += noise_.gyroscope_random_walk * step * normals(stream, 9);
  }
  return cached_;
}

ImuReading ImuErrors::apply(uint64_t sample, const ImuReading& exact) const {
  Biases biases;
  {
    std::lock_guard lock(mutex_);
    biases = biases_at(sample);
  }
  const RandomStream stream = imu_stream(seed_, sample);
  const double root_period = std::sqrt(period_s_);
  ImuReading out;
  out.specific_force =
      exact.specific_force + biases.accel + noise_.accelerometer_noise_density / root_period * normals(stream, 0);
  out.angular_rate = exact.angular_rate + biases.gyro + noise_.gyroscope_g_sensitivity * exact.specific_force +
                     noise_.gyroscope_noise_density / root_period * normals(stream, 3);
  return out;
}

}  // namespace lidartwin
