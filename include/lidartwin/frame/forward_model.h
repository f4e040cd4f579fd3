#pragma once
// The forward model of one sensor: frame k as the lidar packets a real sensor sends (stamped on
// the sensor's clock, status from the column window, headers with init_id, prod_sn and frame_id,
// encoded with their CRC), and the IMU packets on the same clock. The streamer only paces and sends
// what it makes, `record` only writes it, and the analysis calls the same model.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/frame/cast_stage.h"
#include "lidartwin/frame/imu_model.h"
#include "lidartwin/frame/sensor_clock.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/packet/data_format.h"
#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/packet/scan.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/beam_intrinsics.h"
#include "lidartwin/scene/scene.h"

namespace lidartwin {

// What rendering needs to know of a sensor, as configured.
struct RenderSetup {
  BeamIntrinsics beams;  // as served to clients (lidar_frame_azimuth_offset rotates them)
  LidarDataFormat format;
  double max_range_m = 100.0;  // the profile's range limit: the cast looks 1 m beyond it
  EffectChain chain;
  uint64_t seed = 0;
  float signal_gain = 1.0f;  // signal_multiplier
};

struct ForwardModelSetup {
  RenderSetup render;
  // Where the sensor's clock starts (SensorClock; its width and rate come from render.format): the
  // timestamp of frame 0's column 0, and the pose source's time then.
  uint64_t origin_ns = 0;
  double pose_origin_s = 0.0;
  uint32_t init_id = 0;  // header fields of every packet (4.3)
  uint64_t prod_sn = 0;
  // Each column cast from the pose at its own time (as a sensor moves while it spins); false casts
  // every column of a frame from the frame's first column's pose, to show what motion distortion does.
  bool per_column_poses = true;
  // The IMU's errors (the profile's "imu"; zero: exact), drawn from render.seed.
  ImuNoise imu_noise;
};

// A frame's worth of output, owned and reused by the caller (no allocation per frame).
struct EncodedFrame {
  Scan scan;                   // the frame's columns, which its packets are encoded from
  FrameColumns columns;        // poses and observed columns of the frame
  std::vector<uint8_t> bytes;  // the frame's packets back to back, in packet_columns() order
};

class ForwardModel {
 public:
  // scene, poses and pool must outlive the model. Throws InputError naming a format the packet
  // encoder cannot carry.
  ForwardModel(const Scene& scene, const PoseSource& poses, ForwardModelSetup setup, WorkerPool& pool);
  ~ForwardModel();
  ForwardModel(const ForwardModel&) = delete;
  ForwardModel& operator=(const ForwardModel&) = delete;

  const LidarDataFormat& format() const;
  const SensorClock& clock() const;
  const BeamGeometry& geometry() const;
  float cast_range_m() const;  // Embree's tfar: where the cast stops looking for a surface
  // First measurement ids of the packets each frame sends (packets_to_send), in send order.
  const std::vector<int>& packet_columns() const;
  size_t packet_size() const;
  EncodedFrame make_frame_buffer() const;

  // Renders packets [begin, end) (indices into packet_columns()) of frame k into out. Each packet
  // is encoded by the worker that finished its columns. A column is observed when it lies in the
  // column window (6.4) and the pose source answers for its time; others go out with status 0 and
  // zero pixels. The same frame is byte-identical for any thread count or packet split. Returns
  // the number of columns in the window that went out unobserved for want of a pose.
  size_t render(uint64_t frame, size_t begin, size_t end, EncodedFrame& out) const;
  size_t render(uint64_t frame, EncodedFrame& out) const { return render(frame, 0, packet_columns().size(), out); }
  // The same, calling ready(index) on the worker that encoded packet `index`, as soon as its bytes
  // and its columns in out are final: a writer can take packets while the rest still render, on
  // the render threads themselves (`record`), instead of a thread of its own competing for cores;
  // the streamer publishes each packet to its send clock this way.
  using PacketReady = std::function<void(size_t index)>;
  size_t render(uint64_t frame, EncodedFrame& out, const PacketReady& ready) const;
  size_t render(uint64_t frame, size_t begin, size_t end, EncodedFrame& out, const PacketReady& ready) const;
  // Whether packet `index` of a rendered frame has any observed column.
  bool packet_observed(const EncodedFrame& frame, size_t index) const;
  const PoseSource& poses() const;
  std::span<const uint8_t> packet(const EncodedFrame& frame, size_t index) const;
  // When packet `index` of frame k leaves the sensor: its last column's timestamp (protocol doc 1).
  uint64_t packet_timestamp_ns(uint64_t frame, size_t index) const;
  // Packet `index` of frame k with no observed column but its true timestamps, ids and frame_id:
  // what the daemon sends when rendering has fallen behind. Encoded into scratch's slot for it;
  // scratch is a buffer kept for blank packets only (its pixels must stay zero).
  std::span<const uint8_t> blank_packet(uint64_t frame, size_t index, EncodedFrame& scratch) const;

  // IMU sample i (100 Hz from the clock's origin), read from the motion at clock.imu_pose_time_s(i)
  // at the IMU's position and in its axes (imu_to_sensor_transform), with the profile's IMU errors,
  // stamped clock.imu_timestamp_ns(i), as a LEGACY IMU packet (5.1).
  void imu_packet(uint64_t sample, std::span<uint8_t, kLegacyImuPacketSize> out) const;

 private:
  size_t render_packets(uint64_t frame, size_t begin, size_t end, EncodedFrame& out, const PacketReady& ready) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
