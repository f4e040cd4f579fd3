#pragma once
// `lidartwin record`'s engine: renders frames as fast as the machine allows and writes
// capture.pcap (lidar on 7502, LEGACY IMU on 7503), metadata.json and poses.tum.
#include <cstdint>
#include <filesystem>
#include <functional>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/render/frame_renderer.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin::cli {

struct Recording {
  const Scene& scene;
  const SensorProfile& profile;
  const Trajectory& trajectory;
  EffectChain chain;
  Metadata metadata;
  RenderConfig render;
  int frames = 1;
  std::filesystem::path out_dir;
};

// Times: frame k starts at trajectory time t0 + k / fps (t0 = trajectory.start_s()); column m of it
// is observed at that + m / (W * fps) (protocol doc 6.1) and cast from the pose at that time.
// Every timestamp in the capture (column timestamps, IMU sys_ts, pcap record times) is that
// trajectory time in ns, so the capture and poses.tum share one clock. A lidar packet's pcap time
// is its last column's timestamp (when it would leave the sensor).
// poses.tum: one row per frame, world_from_sensor at the frame's start time t0 + k / fps, which is
// the time of its column m = 0 (and that column's timestamp, in seconds).
// progress(frames_done) is called after each frame.
void record(const Recording& recording, const std::function<void(int frames_done)>& progress);

}  // namespace lidartwin::cli
