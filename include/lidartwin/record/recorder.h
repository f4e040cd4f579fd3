#pragma once
// A capture recorded offline, as `lidartwin record` makes it: the forward model renders frames as
// fast as the machine allows and they are written as a real sensor's capture: capture.pcap (lidar on 7502, LEGACY IMU
// on 7503), metadata.json and poses.tum.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

// A sensor streams about half a minute after power-on (boot and spin-up).
inline constexpr double kDefaultUptimeS = 30.0;

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
  // The sensor's time since power-on when frame 0 starts: TIME_FROM_INTERNAL_OSC counts from
  // power-on (protocol doc 6.3), so a real capture never starts at 0 ns.
  double uptime_s = kDefaultUptimeS;
  // When set (a signal handler's flag), the capture ends after the frame being rendered, every file
  // complete up to it: the capture is written in blocks, so stopping the process itself would lose
  // the last ones and cut a record short.
  const std::atomic<bool>* stop = nullptr;
};

// Times: frame k starts at pose time t0 + k / fps, t0 = poses.start_s(), and column m of it is
// observed m / (W * fps) later (protocol doc 6.1) and cast from the pose at that time. The sensor's
// clock (TIME_FROM_INTERNAL_OSC) reads uptime_s at frame 0's column 0 and runs with the pose time;
// every timestamp in the capture (column timestamps, IMU sys_ts, pcap record times) is on it, and
// so are the ground truth files: a lidar packet's pcap time is its last column's timestamp (when
// it would leave the sensor).
// poses.tum: one row per frame, world_from_sensor at the frame's column 0, stamped with that
// column's timestamp in seconds, plus one where the last frame ends; column_poses.tum: the pose
// each observed column was cast from, at its timestamp, written only when the pose varies (not for
// a PoseSource that is constant(): a fixed --pose, or a trajectory of one pose).
// progress(frames_done) is called after each frame. Returns the frames recorded: `frames`, or fewer
// if `stop` was set.
int record(const Recording& recording, const std::function<void(int frames_done)>& progress);

}  // namespace lidartwin
