#pragma once
// One StreamConfig's worth of streaming: the lidar column clock and the IMU clock, from a reinit to
// the next one (protocol doc 2.7: a reinit restarts UDP with a new init_id and frame_id sequence).
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <asio.hpp>

#include "lidartwin/frame/forward_model.h"
#include "lidartwin/sensor/stream_config.h"
#include "streamer/fault_injector.h"
#include "streamer/ground_truth.h"
#include "streamer/render_ahead.h"
#include "streamer/session_timing.h"
#include "streamer/stream_counters.h"

namespace lidartwin::streamer_detail {

// Lives in a shared_ptr: every pending timer handler holds it, as Asio's connection examples do,
// so stop() followed by io_context::run() returning leaves nothing dangling.
//
// Timing policy (protocol doc 1 items 11-12): packet k of frame n is sent when its last column's
// time has come, from absolute deadlines (start + column time), never "sleep one period".
// - A packet whose columns the worker has not finished by its deadline is sent on time anyway,
//   with its columns marked invalid (status 0, zero pixels) but correct timestamps, ids and
//   frame_id, and counted as a render stall: the client's scan stays complete and on time, and the
//   daemon warns (StreamStats::render_stalls). Timing is never bent to wait for the renderer.
// - Packets overdue by more than one frame period (the process was descheduled for that long)
//   are skipped and counted, rather than flushed as a burst that would overflow the client's
//   receive buffer (item 12).
// - When the motion ends (PoseSource::end_s(), serve --trajectory-end stop), the frames that
//   started before it are sent whole, so a client's last scan is complete, and nothing after them,
//   lidar or IMU.
class StreamSession : public std::enable_shared_from_this<StreamSession> {
 public:
  // The session renders ahead with `model` when the lidar stream is on (udp_port_lidar != 0) and
  // sends IMU packets when send_imu. link and counters must outlive the session (the Streamer
  // owns them).
  struct Options {
    bool send_imu = false;
    int frames_ahead = 2;
    int render_nice = 0;
    // Wake this much before a lidar deadline, then spin to it. The streamer's, which it changes
    // with the host's load (it outlives the session); null: never spin.
    const int64_t* spin_ns = nullptr;
    // Wake for the packets due within this much together, the earlier ones held back, and send
    // the IMU samples due with them (StreamerOptions::coalesce_us). The streamer's; null: never.
    const int64_t* coalesce_ns = nullptr;
    int64_t cast_ahead_ns = 0;      // > 0: cast each packet only this long before it is due
    PoseNews* pose_news = nullptr;  // with cast_ahead_ns: says when a pose arrived (outlives the session)
    bool withhold_unposed = false;  // do not send packets none of whose columns had a pose
    // The simulator owns time: no timers; advance_to() casts and sends what is due, in order.
    bool lock_step = false;
  };
  // link: the socket, through the fault plan. ground_truth: where sent columns' poses are written
  // (serve --record), or null.
  StreamSession(asio::io_context& io, FaultInjector& link, StreamCounters& counters, GroundTruth* ground_truth,
                std::shared_ptr<const StreamConfig> config, std::unique_ptr<ForwardModel> model, SessionTiming timing,
                Options options);
  void start();
  // Io thread: cancels both clocks; the handlers still pending find the session stopped.
  void stop();
  // After stop(), on any thread: joins the render worker and frees the model and the buffers (the
  // Streamer does it off the io thread: background_jobs.h).
  void release();
  // Lock-step: casts and sends, in order, every lidar and IMU packet stamped up to time_ns (the
  // session's clock, which in lock-step is the simulation's). On the io thread.
  void advance_to(uint64_t time_ns);
  uint64_t take_render_busy_ns() { return render_ ? render_->take_busy_ns() : 0; }
  uint64_t take_unposed_columns() { return render_ ? render_->take_unposed_columns() : 0; }
  uint64_t take_recasts() { return render_ ? render_->take_recasts() : 0; }

 private:
  int64_t deadline_ns(uint64_t frame, size_t index) const;
  int64_t lidar_deadline_ns() const;
  void arm_lidar();
  void on_lidar_deadline();
  void send_lidar_packet(int64_t now_ns);
  void advance_lidar();
  void skip_overdue_lidar(int64_t now_ns);
  int64_t coalesce_ns() const;
  void send_due_imu(int64_t now_ns);
  int64_t imu_deadline_ns() const;
  void arm_imu();
  void on_imu_deadline();
  void send_imu_packet();
  bool frame_past_end(uint64_t frame) const;  // starts at or after the motion's end
  bool lidar_ended() const;
  bool imu_ended() const;
  double stream_end_pose_s() const;
  void note_end();

  asio::steady_timer lidar_timer_;
  asio::steady_timer imu_timer_;
  FaultInjector& link_;
  StreamCounters& counters_;
  GroundTruth* ground_truth_;
  std::shared_ptr<const StreamConfig> config_;
  std::unique_ptr<ForwardModel> model_;
  SessionTiming timing_;
  Options options_;
  std::unique_ptr<RenderAhead> render_;  // null without a lidar stream; goes before model_
  size_t packets_per_frame_ = 0;         // 0 without a lidar stream
  EncodedFrame blank_;                   // only for blank packets: its pixels stay zero
  EncodedFrame step_;                    // lock-step: the frame being cast packet by packet
  uint64_t frame_ = 0;
  size_t packet_index_ = 0;
  uint64_t imu_index_ = 0;
  uint64_t imu_arming_ = 0;  // counts arm_imu(): a handler of an earlier arming finds it stale
  bool stopped_ = false;
  bool end_noted_ = false;
};

}  // namespace lidartwin::streamer_detail
