#pragma once
// Between the send clock and the socket: what a FaultPlan does to the datagrams (lost, reordered,
// duplicated, cut short, bad CRC, delayed, frame_id jumped) and when the sensor's own faults (a
// reset, STANDBY, ERROR) are due. Every fault is logged to the FaultControl with the ids a client
// sees (init_id, frame_id, measurement_id), so a client's view can be checked against the log.
#include <cstdint>
#include <functional>
#include <optional>
#include <queue>
#include <span>
#include <string>
#include <vector>

#include <asio.hpp>

#include "lidartwin/fault/fault_control.h"
#include "lidartwin/fault/fault_schedule.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/sensor/stream_config.h"
#include "lidartwin/streamer/streamer.h"
#include "streamer/udp_sender.h"

namespace lidartwin::streamer_detail {

class FaultInjector {
 public:
  // control may be null (no faults: every call goes straight to the sender). on_sensor_fault runs
  // on the io thread when a sensor event is due; the session that reached it sends nothing more.
  FaultInjector(asio::io_context& io, UdpSender& sender, FaultControl* control,
                std::function<void(SensorFaultEvent)> on_sensor_fault);

  // A streaming session starts (sessions are numbered from 0 as the daemon starts them). format
  // is null when the lidar stream is off.
  void start_session(const StreamConfig& config, const PacketFormat* format, int fps);
  // The session ends: datagrams held back or delayed for it are dropped with it.
  void end_session();

  // False when the datagram was not sent: the socket refused it, or a sensor event stopped the
  // session. A datagram the plan loses counts as sent (the sensor sent it; the network lost it).
  bool send_lidar(std::span<const uint8_t> packet, uint64_t frame, size_t packet_index, int first_column,
                  uint16_t port);
  bool send_imu(std::span<const uint8_t> packet, uint64_t sample, uint16_t port);
  // The session finished sending `frame`. Returns true when a sensor event fired (on_sensor_fault ran).
  bool frame_finished(uint64_t frame);

 private:
  struct Delayed {
    int64_t due_ns;
    uint64_t order;  // FIFO among equal due times
    Ipv4 destination;
    uint16_t port;
    std::vector<uint8_t> bytes;
    bool operator>(const Delayed& other) const {
      return due_ns != other.due_ns ? due_ns > other.due_ns : order > other.order;
    }
  };
  struct Held {
    uint16_t port = 0;
    std::vector<uint8_t> bytes;
    int64_t delay_ns = 0;
  };

  bool active();  // refreshes the plan; false when there is nothing to inject
  bool send_faulted(FaultStream stream, uint16_t port, std::span<const uint8_t> datagram, uint64_t sequence,
                    nlohmann::json where, std::optional<Held>& held);
  bool transmit(uint16_t port, std::span<const uint8_t> datagram, int64_t delay_ns);
  void arm_delay_timer();
  void release_delayed();
  std::optional<SensorFaultEvent> due_sensor_fault(uint64_t frame);

  asio::steady_timer delay_timer_;
  UdpSender& sender_;
  FaultControl* control_;
  std::function<void(SensorFaultEvent)> on_sensor_fault_;

  FaultPlan plan_;
  uint64_t plan_generation_ = 0;
  uint64_t frames_under_plan_ = 0;  // frames streamed since the plan took effect
  bool reset_fired_ = false, standby_fired_ = false, error_fired_ = false;

  // The session's.
  std::optional<uint64_t> session_;  // counts from 0
  Ipv4 destination_{};
  uint32_t init_id_ = 0;
  std::optional<PacketFormat> format_;
  int fps_ = 10;
  bool halted_ = false;
  std::optional<uint64_t> jump_checked_frame_;
  uint64_t frame_offset_ = 0;  // frame_id = frame_id_of(frame + offset)
  std::optional<Held> held_lidar_, held_imu_;
  std::vector<uint8_t> scratch_;
  std::priority_queue<Delayed, std::vector<Delayed>, std::greater<>> delayed_;
  uint64_t delayed_order_ = 0;
  uint64_t sessions_started_ = 0;
};

}  // namespace lidartwin::streamer_detail
