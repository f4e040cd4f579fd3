#include "streamer/stream_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <spdlog/spdlog.h>

#include "lidartwin/packet/imu_packet.h"

namespace lidartwin::streamer_detail {

namespace {
void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

asio::steady_timer::time_point steady_time(int64_t ns) {
  return asio::steady_timer::time_point(std::chrono::nanoseconds(ns));
}
}  // namespace

StreamSession::StreamSession(asio::io_context& io, FaultInjector& link, StreamCounters& counters,
                             GroundTruth* ground_truth, std::shared_ptr<const StreamConfig> config,
                             std::unique_ptr<ForwardModel> model, SessionTiming timing, Options options)
    : lidar_timer_(io),
      imu_timer_(io),
      link_(link),
      counters_(counters),
      ground_truth_(ground_truth),
      config_(std::move(config)),
      model_(std::move(model)),
      timing_(timing),
      options_(options) {
  if (config_->udp_port_lidar == 0) return;
  packets_per_frame_ = model_->packet_columns().size();
  if (options_.lock_step) {
    step_ = model_->make_frame_buffer();
    return;
  }
  render_ = std::make_unique<RenderAhead>(
      *model_, timing_, RenderAhead::Options{options_.frames_ahead, options_.render_nice, options_.cast_ahead_ns},
      options_.pose_news);
  blank_ = model_->make_frame_buffer();
}

// A session built off the io thread can start after its first frames were due, when the host is
// busy: it begins with the first frame that has not begun yet, as a sensor whose reinit took longer
// would, rather than sending those frames late or counting them as skipped (IMU samples alike).
void StreamSession::start() {
  if (options_.lock_step) return;
  const int64_t now = steady_now_ns();
  if (packets_per_frame_ > 0) {
    const uint64_t first = frame_;
    while (timing_.steady_ns_of_timestamp(timing_.clock.column_timestamp_ns(frame_, 0)) < now) ++frame_;
    if (frame_ > first) {
      render_->finished(frame_ - 1);
      spdlog::info("streamer: the session was ready {} frames late (a busy host): it starts with frame {}",
                   frame_ - first, frame_);
    }
    arm_lidar();
  }
  if (options_.send_imu) {
    while (imu_deadline_ns() < now) ++imu_index_;
    arm_imu();
  }
}

// Nothing is skipped or sent late here: a simulator running slower or faster than real time gets
// every packet of every frame, stamped on its clock, as soon as its time has come.
void StreamSession::advance_to(uint64_t time_ns) {
  if (stopped_) return;
  while (packets_per_frame_ > 0 && !lidar_ended() && model_->packet_timestamp_ns(frame_, packet_index_) <= time_ns) {
    counters_.stats.columns_without_pose += model_->render(frame_, packet_index_, packet_index_ + 1, step_);
    if (link_.send_lidar(model_->packet(step_, packet_index_), frame_, packet_index_,
                         model_->packet_columns()[packet_index_], config_->udp_port_lidar)) {
      ++counters_.stats.lidar_packets_sent;
      if (ground_truth_) ground_truth_->packet_sent(*model_, frame_, packet_index_, step_);
    }
    advance_lidar();
  }
  while (options_.send_imu && !imu_ended() && timing_.clock.imu_timestamp_ns(imu_index_) <= time_ns) send_imu_packet();
}

void StreamSession::stop() {
  stopped_ = true;
  lidar_timer_.cancel();
  imu_timer_.cancel();
}

// Handlers run on the io thread and check stopped_ first, so what they would read can go now,
// rather than when the last cancelled handler releases the session.
void StreamSession::release() {
  render_.reset();  // before the model it renders with
  model_.reset();
  blank_ = {};
  step_ = {};
}

// The packet's timestamp (its last column's) on the steady clock.
int64_t StreamSession::deadline_ns(uint64_t frame, size_t index) const {
  return timing_.steady_ns_of_timestamp(model_->packet_timestamp_ns(frame, index));
}

int64_t StreamSession::lidar_deadline_ns() const { return deadline_ns(frame_, packet_index_); }

// The timer fires spin_ns early, and the handler spins to the exact deadline: waking a sleeping
// thread costs tens of microseconds on a virtual machine, more than item 12's pacing should drift.
// Coalesced (a contended host: StreamerOptions::coalesce_us), it wakes at the last deadline within
// the window after the next one and sends every packet then due: a packet is held back for a later
// one's wake-up, never sent before its time (a real sensor never is; a late one looks like a
// network's delay), and its columns get that much longer to be cast.
void StreamSession::arm_lidar() {
  int64_t wake_ns = lidar_deadline_ns();
  if (const int64_t window = coalesce_ns(); window > 0) {
    const int64_t latest = wake_ns + window;
    uint64_t frame = frame_;
    size_t index = packet_index_;
    for (;;) {
      if (++index == packets_per_frame_) {
        if (frame_past_end(frame + 1)) break;
        ++frame;
        index = 0;
      }
      const int64_t deadline = deadline_ns(frame, index);
      if (deadline > latest) break;
      wake_ns = deadline;
    }
  }
  lidar_timer_.expires_at(steady_time(wake_ns - (options_.spin_ns ? *options_.spin_ns : 0)));
  lidar_timer_.async_wait([self = shared_from_this()](const asio::error_code& error) {
    if (!error && !self->stopped_) self->on_lidar_deadline();
  });
}

void StreamSession::on_lidar_deadline() {
  int64_t now = steady_now_ns();
  while (now < lidar_deadline_ns()) {  // at most *spin_ns: the packet is due when its column is
    cpu_relax();
    now = steady_now_ns();
  }
  skip_overdue_lidar(now);
  // Normally exactly one packet is due (coalesced, a few); after a short delay, every packet whose
  // time has come.
  while (lidar_deadline_ns() <= now) {
    if (lidar_ended()) {
      note_end();
      return;  // not armed again: the stream is over
    }
    send_lidar_packet(now);
    advance_lidar();
    now = steady_now_ns();
  }
  send_due_imu(now);
  arm_lidar();
}

int64_t StreamSession::coalesce_ns() const { return options_.coalesce_ns ? *options_.coalesce_ns : 0; }

// Coalesced, the IMU samples due by a lidar wake-up go with it (100 Hz against 320 wake-ups a
// second at 1024x10), and the IMU's own clock waits a window longer in case none comes: while the
// lidar streams, the IMU then wakes nobody.
void StreamSession::send_due_imu(int64_t now_ns) {
  if (!options_.send_imu || coalesce_ns() <= 0 || imu_ended() || imu_deadline_ns() > now_ns) return;
  while (!imu_ended() && imu_deadline_ns() <= now_ns) send_imu_packet();
  arm_imu();  // for the next sample: the pending wait is for one just sent
}

void StreamSession::send_lidar_packet(int64_t now_ns) {
  // One read of what the worker published: the bytes, poses and freshness of one copy (render_ahead.h).
  const std::optional<RenderAhead::Ready> ready = render_->ready(frame_, packet_index_);
  std::span<const uint8_t> bytes;
  if (ready) {
    bytes = ready->bytes;
    if (options_.withhold_unposed && !model_->packet_observed(*ready->encoded, packet_index_)) {
      ++counters_.stats.withheld_packets;
      return;
    }
  } else {
    ++counters_.stats.render_stalls;
    bytes = model_->blank_packet(frame_, packet_index_, blank_);
  }
  if (link_.send_lidar(bytes, frame_, packet_index_, model_->packet_columns()[packet_index_],
                       config_->udp_port_lidar)) {
    counters_.record_lidar_send(now_ns - lidar_deadline_ns(), coalesce_ns());
    // A blank (stalled) packet was cast with no pose, and its slot may be mid-render: only a packet
    // the worker published reports the poses it carries.
    if (!ready) return;
    counters_.record_pose_use(ready->freshness, now_ns);
    if (ground_truth_) ground_truth_->packet_sent(*model_, frame_, packet_index_, *ready->encoded);
  }
}

void StreamSession::advance_lidar() {
  if (++packet_index_ < packets_per_frame_) return;
  if (render_) render_->finished(frame_);
  ++counters_.stats.frames_sent;
  link_.frame_finished(frame_);  // a sensor fault due now stops this session's sending
  ++frame_;
  packet_index_ = 0;
}

void StreamSession::skip_overdue_lidar(int64_t now_ns) {
  const auto limit = static_cast<int64_t>(timing_.clock.frame_period_ns());
  while (now_ns - lidar_deadline_ns() > limit) {
    ++counters_.skipped_packets;
    advance_lidar();
  }
}

int64_t StreamSession::imu_deadline_ns() const {
  return timing_.steady_ns_of_timestamp(timing_.clock.imu_timestamp_ns(imu_index_));
}

void StreamSession::arm_imu() {
  const int64_t held_ns = packets_per_frame_ > 0 && !lidar_ended() ? coalesce_ns() : 0;  // send_due_imu()
  imu_timer_.expires_at(steady_time(imu_deadline_ns() + held_ns));                       // cancels a pending wait
  imu_timer_.async_wait([self = shared_from_this(), arming = ++imu_arming_](const asio::error_code& error) {
    // An earlier arming's handler can be queued already when send_due_imu() re-arms.
    if (!error && !self->stopped_ && arming == self->imu_arming_) self->on_imu_deadline();
  });
}

// LEGACY IMU at 100 Hz (5.1), stamped in the lidar's clock so both streams share a timebase.
void StreamSession::on_imu_deadline() {
  const int64_t now = steady_now_ns();
  while (now - imu_deadline_ns() > static_cast<int64_t>(timing_.clock.frame_period_ns())) {  // see skip_overdue_lidar
    ++counters_.imu_skipped;
    ++imu_index_;
  }
  if (imu_ended()) {
    note_end();
    return;
  }
  send_imu_packet();
  arm_imu();
}

void StreamSession::send_imu_packet() {
  std::array<uint8_t, kLegacyImuPacketSize> bytes{};
  model_->imu_packet(imu_index_, bytes);
  if (link_.send_imu(bytes, imu_index_, config_->udp_port_imu)) ++counters_.stats.imu_packets_sent;
  ++imu_index_;
}

// The pose time at which streaming ends: the start of the first frame that starts at or after the
// motion's end (frame starts as SensorClock::column_pose_time_s computes them, so they compare
// exactly). +infinity while the motion has no end.
double StreamSession::stream_end_pose_s() const {
  const double end_s = model_->poses().end_s();
  if (std::isinf(end_s)) return end_s;
  const SensorClock& clock = timing_.clock;
  const double frames = std::max(0.0, std::ceil((end_s - clock.pose_origin_s) * clock.fps));
  return clock.pose_origin_s + frames / clock.fps;
}

bool StreamSession::frame_past_end(uint64_t frame) const {
  return timing_.clock.column_pose_time_s(frame, 0) >= stream_end_pose_s();
}

bool StreamSession::lidar_ended() const { return frame_past_end(frame_); }

bool StreamSession::imu_ended() const { return timing_.clock.imu_pose_time_s(imu_index_) >= stream_end_pose_s(); }

void StreamSession::note_end() {
  if (end_noted_) return;
  end_noted_ = true;
  spdlog::info(
      "streamer: the motion ended (trajectory end \"stop\"): streaming stopped after frame {}, pose time {:.3f} s",
      frame_, stream_end_pose_s());
}

}  // namespace lidartwin::streamer_detail
