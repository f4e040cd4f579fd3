#pragma once
// What the IMU measures along the sensor's motion (protocol doc 5.1): specific force in g and angular rate
// in deg/s, in the IMU frame. imu_to_sensor_transform has translation only (5.1), so the IMU axes
// are the sensor axes; the lever arm between them is ignored (its effect is below 1 mg here).
#include <cstdint>

#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/pose/pose_source.h"

namespace lidartwin {

inline constexpr double kStandardGravity = 9.80665;  // m/s^2, the SDK's g (5.1)

// The sample read at pose time time_s, stamped timestamp_ns (the lidar's clock). Motion comes
// from central differences over +-step_s: a sensor at rest reads (0, 0, +1) g when Z is up.
ImuSample imu_sample(const PoseSource& poses, double time_s, uint64_t timestamp_ns, double step_s = 0.02);

}  // namespace lidartwin
