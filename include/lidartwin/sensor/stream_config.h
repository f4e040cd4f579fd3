#pragma once
// The contract between the sensor state machine and the streamer: what to emit after a reinit, and
// how the stream is doing (reported back into telemetry and logs).
#include <array>
#include <cstdint>
#include <string>

#include "lidartwin/metadata/metadata.h"

namespace lidartwin {

// Immutable snapshot of the active configuration, replaced as a whole on every reinit.
struct StreamConfig {
  uint64_t generation = 0;                        // +1 per reinit: the streamer restarts when it changes
  Metadata metadata;                              // exactly what GET /api/v1/sensor/metadata serves
  std::array<uint8_t, 4> udp_dest{127, 0, 0, 1};  // resolved IPv4 destination
  uint16_t udp_port_lidar = 7502;                 // 0 = lidar stream disabled
  uint16_t udp_port_imu = 7503;                   // 0 = IMU stream disabled
  bool streaming = true;                          // operating_mode NORMAL (false in STANDBY)
  std::string timestamp_mode = "TIME_FROM_INTERNAL_OSC";
  float signal_multiplier = 1.0f;
  uint32_t init_id = 0;  // = metadata.sensor_info.initialization_id (24 bits)
  uint64_t prod_sn = 0;  // numeric prod_sn (40 bits)
};

// Reported by the streamer; served by telemetry and logged when casting cannot keep up.
struct StreamStats {
  uint64_t lidar_packets_sent = 0;
  uint64_t imu_packets_sent = 0;
  uint64_t frames_sent = 0;
  uint64_t late_packets = 0;   // sent more than the lateness threshold after their deadline
  uint64_t render_stalls = 0;  // packets whose columns were not rendered in time
  // Packets not sent at all: due more than a frame ago when the send clock got to them (the host
  // held it up), so that a burst would not overflow the client's receive buffer.
  uint64_t skipped_packets = 0;
  double max_lateness_us = 0.0;
  double lateness_p50_us = 0.0;  // send lateness (sent - due) of every packet sent so far
  double lateness_p99_us = 0.0;
  double render_load = 0.0;  // render time / real time over the last second (1.0 = saturated)
  // The send clock's coalescing window now (StreamerOptions::coalesce_us, coalescing_window.h), 0
  // while it wakes once per packet.
  double coalesce_window_us = 0.0;
  // Live poses (docs/live-poses.md): columns in the window sent unobserved for want of a pose,
  // packets withheld for the same reason (timeout policy "standby"), and the latency from a
  // pose's arrival to the first packet cast with it; packets cast a second time because a pose
  // arrived after their first cast, before they were due.
  uint64_t columns_without_pose = 0;
  uint64_t withheld_packets = 0;
  uint64_t recast_packets = 0;
  uint64_t pose_latency_count = 0;
  double pose_latency_p50_us = 0.0;
  double pose_latency_p99_us = 0.0;
  double pose_latency_max_us = 0.0;
};

}  // namespace lidartwin
