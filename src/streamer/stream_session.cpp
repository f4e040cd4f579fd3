#include "streamer/stream_session.h"

#include <chrono>

#include "lidartwin/packet/imu_packet.h"
#include "lidartwin/streamer/imu_model.h"
#include "lidartwin/streamer/packet_schedule.h"

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

StreamSession::StreamSession(asio::io_context& io, UdpSender& sender, StreamCounters& counters,
                             std::shared_ptr<const StreamConfig> config, const Trajectory& trajectory,
                             SessionTiming timing, std::unique_ptr<RenderAhead> render, bool send_imu,
                             int64_t spin_ns)
    : lidar_timer_(io),
      imu_timer_(io),
      sender_(sender),
      counters_(counters),
      config_(std::move(config)),
      trajectory_(trajectory),
      timing_(timing),
      render_(std::move(render)),
      send_imu_(send_imu),
      spin_ns_(spin_ns) {
  if (!render_) return;
  packet_columns_ = render_->packet_columns();
  packet_format_ = std::make_unique<PacketFormat>(config_->metadata.format);
  blank_scan_ = Scan(config_->metadata.format);
  blank_bytes_.resize(packet_format_->lidar_packet_size());
}

void StreamSession::start() {
  if (render_ && !packet_columns_.empty()) arm_lidar();
  if (send_imu_) arm_imu();
}

void StreamSession::stop() {
  stopped_ = true;
  lidar_timer_.cancel();
  imu_timer_.cancel();
  // Handlers run on this thread and check stopped_ first, so the worker can go now rather than
  // when the last cancelled handler releases the session.
  render_.reset();
}

int64_t StreamSession::lidar_deadline_ns() const {
  const int first = packet_columns_[packet_index_];
  const uint64_t offset = packet_deadline_offset_ns(timing_.clock, first, config_->metadata.format.columns_per_packet);
  return timing_.start_steady_ns + static_cast<int64_t>(timing_.clock.frame_start_ns(frame_) + offset);
}

// The timer fires spin_ns early, and the handler spins to the exact deadline: waking a sleeping
// thread costs tens of microseconds on a virtual machine, more than item 12's pacing should drift.
void StreamSession::arm_lidar() {
  lidar_timer_.expires_at(steady_time(lidar_deadline_ns() - spin_ns_));
  lidar_timer_.async_wait([self = shared_from_this()](const asio::error_code& error) {
    if (!error && !self->stopped_) self->on_lidar_deadline();
  });
}

void StreamSession::on_lidar_deadline() {
  int64_t now = steady_now_ns();
  while (now < lidar_deadline_ns()) {  // at most spin_ns: the packet is due when its column is
    cpu_relax();
    now = steady_now_ns();
  }
  skip_overdue_lidar(now);
  // Normally exactly one packet is due; after a short delay, every packet whose time has come.
  while (lidar_deadline_ns() <= now) {
    send_lidar_packet(now);
    advance_lidar();
    now = steady_now_ns();
  }
  arm_lidar();
}

void StreamSession::send_lidar_packet(int64_t now_ns) {
  std::span<const uint8_t> bytes = render_->packet(frame_, packet_index_);
  if (bytes.empty()) {
    ++counters_.stats.render_stalls;
    bytes = blank_packet();
  }
  if (sender_.send(config_->udp_dest, config_->udp_port_lidar, bytes)) {
    counters_.record_lidar_send(now_ns - lidar_deadline_ns());
  }
}

// The packet the renderer did not finish in time: right ids and timestamps, no valid columns.
std::span<const uint8_t> StreamSession::blank_packet() {
  const int first = packet_columns_[packet_index_];
  const auto& format = config_->metadata.format;
  for (int m = first; m < first + format.columns_per_packet; ++m) {
    blank_scan_.timestamp_ns[static_cast<size_t>(m)] = timing_.column_timestamp_ns(frame_, m);
  }
  PacketHeader header;
  header.frame_id = frame_id_of(frame_, format);
  header.init_id = config_->init_id;
  header.prod_sn = config_->prod_sn;
  packet_format_->encode(header, blank_scan_, first, blank_bytes_);
  return blank_bytes_;
}

void StreamSession::advance_lidar() {
  if (++packet_index_ < packet_columns_.size()) return;
  render_->finished(frame_);
  ++counters_.stats.frames_sent;
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

void StreamSession::arm_imu() {
  const int64_t deadline = timing_.start_steady_ns + static_cast<int64_t>(imu_index_ * kImuPeriodNs);
  imu_timer_.expires_at(steady_time(deadline));
  imu_timer_.async_wait([self = shared_from_this()](const asio::error_code& error) {
    if (!error && !self->stopped_) self->on_imu_deadline();
  });
}

// LEGACY IMU at 100 Hz (5.1), stamped in the lidar's clock so both streams share a timebase.
void StreamSession::on_imu_deadline() {
  const int64_t now = steady_now_ns();
  int64_t deadline = timing_.start_steady_ns + static_cast<int64_t>(imu_index_ * kImuPeriodNs);
  while (now - deadline > static_cast<int64_t>(timing_.clock.frame_period_ns())) {  // see skip_overdue_lidar
    ++counters_.imu_skipped;
    deadline = timing_.start_steady_ns + static_cast<int64_t>(++imu_index_ * kImuPeriodNs);
  }
  const auto timestamp = static_cast<uint64_t>(deadline + timing_.timestamp_offset_ns);
  const ImuSample sample = imu_sample(trajectory_, timing_.trajectory_time_s(deadline), timestamp);
  std::array<uint8_t, kLegacyImuPacketSize> bytes{};
  encode_legacy_imu(sample, bytes);
  if (sender_.send(config_->udp_dest, config_->udp_port_imu, bytes)) ++counters_.stats.imu_packets_sent;
  ++imu_index_;
  arm_imu();
}

}  // namespace lidartwin::streamer_detail
