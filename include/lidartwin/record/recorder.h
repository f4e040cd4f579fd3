#pragma once
// A capture recorded offline, as `lidartwin record` makes it: the forward model renders frames as
// fast as the machine allows and they are written as a real sensor's capture: capture.pcap (lidar on 7502, LEGACY IMU
// on 7503), metadata.json and poses.tum.
#include <cstdint>
#include <filesystem>
#include <functional>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

struct Recording {
  const Scene& scene;
  const PoseSource& poses;
  double max_range_m = 100.0;  // the profile's range limit
  EffectChain chain;
  Metadata metadata;
  uint64_t seed = 0;
  int threads = 0;  // 0 = all cores
  int frames = 1;
  std::filesystem::path out_dir;
  ImuNoise imu_noise = {};  // the profile's IMU errors (zero: exact)
};

// Times: the sensor clock's origin is the pose source's start t0 = poses.start_s(): frame k starts
// at t0 + k / fps, column m of it is observed m / (W * fps) later (protocol doc 6.1) and cast from
// the pose at that time. Every timestamp in the capture (column timestamps, IMU sys_ts, pcap record
// times) is that time in ns, so the capture and poses.tum share one clock. A lidar packet's pcap
// time is its last column's timestamp (when it would leave the sensor).
// poses.tum: one row per frame, world_from_sensor at the frame's start t0 + k / fps, which is the
// time of its column m = 0 (and that column's timestamp, in seconds).
// progress(frames_done) is called after each frame.
void record(const Recording& recording, const std::function<void(int frames_done)>& progress);

}  // namespace lidartwin
