#include "streamer/fault_injector.h"

#include <cmath>

#include "lidartwin/packet/data_format.h"
#include "streamer/session_timing.h"

namespace lidartwin::streamer_detail {

using nlohmann::json;

namespace {
asio::steady_timer::time_point steady_point(int64_t ns) {
  return asio::steady_timer::time_point(std::chrono::nanoseconds(ns));
}
}  // namespace

FaultInjector::FaultInjector(asio::io_context& io, UdpSender& sender, FaultControl* control,
                             std::function<void(SensorFaultEvent)> on_sensor_fault)
    : delay_timer_(io), sender_(sender), control_(control), on_sensor_fault_(std::move(on_sensor_fault)) {}

bool FaultInjector::active() {
  if (!control_) return false;
  const uint64_t generation = control_->generation();
  if (generation != plan_generation_) {
    plan_ = control_->plan();
    plan_generation_ = generation;
    frames_under_plan_ = 0;
    reset_fired_ = standby_fired_ = error_fired_ = false;
  }
  return !plan_.empty();
}

void FaultInjector::start_session(const StreamConfig& config, const PacketFormat* format, int fps) {
  end_session();
  session_ = sessions_started_++;
  destination_ = config.udp_dest;
  init_id_ = config.init_id;
  if (format) {
    format_.emplace(*format);
  } else {
    format_.reset();
  }
  fps_ = fps;
  halted_ = false;
  jump_checked_frame_.reset();
  frame_offset_ = 0;
}

// What the network still holds arrives: a datagram held back for reordering with nothing after it
// to overtake it, and delayed ones, go out now, so a session's end loses nothing the log does not say.
void FaultInjector::end_session() {
  for (std::optional<Held>* held : {&held_lidar_, &held_imu_}) {
    if (*held) sender_.send(destination_, (*held)->port, (*held)->bytes);
    held->reset();
  }
  while (!delayed_.empty()) {
    sender_.send(delayed_.top().destination, delayed_.top().port, delayed_.top().bytes);
    delayed_.pop();
  }
  delay_timer_.cancel();
}

bool FaultInjector::send_lidar(std::span<const uint8_t> packet, uint64_t frame, size_t packet_index, int first_column,
                               uint16_t port) {
  if (halted_) return false;
  if (!active() || !format_) return sender_.send(destination_, port, packet);
  // frame_id jumps: checked once per frame, at its first packet; from then on every packet of the
  // session carries the offset.
  if (!jump_checked_frame_ || *jump_checked_frame_ != frame) {
    jump_checked_frame_ = frame;
    if (frame_jumps(plan_, *session_, frame)) {
      const uint32_t from = frame_id_of(frame + frame_offset_, format_->format());
      frame_offset_ += static_cast<uint64_t>(plan_.frame_jump_by);
      control_->record("frame_jump", {{"stream", "lidar"},
                                      {"init_id", init_id_},
                                      {"frame", frame},
                                      {"frame_id_expected", from},
                                      {"frame_id", frame_id_of(frame + frame_offset_, format_->format())}});
    }
  }
  const uint32_t frame_id = frame_id_of(frame + frame_offset_, format_->format());
  if (frame_offset_ != 0) {
    scratch_.assign(packet.begin(), packet.end());
    format_->set_frame_id(scratch_, frame_id);
    packet = scratch_;
  }
  const uint64_t sequence = frame * 1'000'000 + packet_index;  // packets per frame < 10^6
  json where{{"stream", "lidar"}, {"init_id", init_id_},   {"frame_id", frame_id}, {"measurement_id", first_column},
             {"frame", frame},    {"packet", packet_index}};
  return send_faulted(FaultStream::kLidar, port, packet, sequence, std::move(where), held_lidar_);
}

bool FaultInjector::send_imu(std::span<const uint8_t> packet, uint64_t sample, uint16_t port) {
  if (halted_) return false;
  if (!active()) return sender_.send(destination_, port, packet);
  return send_faulted(FaultStream::kImu, port, packet, sample,
                      {{"stream", "imu"}, {"init_id", init_id_}, {"sample", sample}}, held_imu_);
}

bool FaultInjector::send_faulted(FaultStream stream, uint16_t port, std::span<const uint8_t> datagram,
                                 uint64_t sequence, json where, std::optional<Held>& held) {
  const DatagramFate fate = datagram_fate(plan_, stream, *session_, sequence, datagram.size());
  if (fate.lost) {
    control_->record("loss", std::move(where));
    return true;
  }
  if (fate.reordered && !held) {  // one held at a time: a second draw in a row goes out normally
    held = Held{port, std::vector<uint8_t>(datagram.begin(), datagram.end()), fate.delay_ns};
    control_->record("reorder", std::move(where));
    return true;
  }
  if (fate.truncated_to > 0) {
    where["bytes"] = fate.truncated_to;
    control_->record("truncate", std::move(where));
    datagram = datagram.first(fate.truncated_to);
  } else if (fate.bad_crc && format_ && format_->has_crc()) {
    if (scratch_.data() != datagram.data()) scratch_.assign(datagram.begin(), datagram.end());
    scratch_.back() ^= 0x01;  // the CRC's top byte: any flipped bit is a bad CRC
    datagram = scratch_;
    control_->record("bad_crc", std::move(where));
  } else if (fate.duplicated) {
    control_->record("duplicate", where);
  }
  const bool sent = transmit(port, datagram, fate.delay_ns);
  if (fate.duplicated) transmit(port, datagram, fate.delay_ns);
  if (held) {
    const Held late = std::move(*held);
    held.reset();
    transmit(late.port, late.bytes, late.delay_ns);
  }
  return sent;
}

bool FaultInjector::transmit(uint16_t port, std::span<const uint8_t> datagram, int64_t delay_ns) {
  if (delay_ns <= 0) return sender_.send(destination_, port, datagram);
  const bool was_empty = delayed_.empty();
  const int64_t due = steady_now_ns() + delay_ns;
  const bool earliest = was_empty || due < delayed_.top().due_ns;
  delayed_.push(
      Delayed{due, delayed_order_++, destination_, port, std::vector<uint8_t>(datagram.begin(), datagram.end())});
  if (earliest) arm_delay_timer();
  return true;
}

void FaultInjector::arm_delay_timer() {
  if (delayed_.empty()) return;
  delay_timer_.expires_at(steady_point(delayed_.top().due_ns));
  delay_timer_.async_wait([this](const asio::error_code& error) {
    if (!error) release_delayed();
  });
}

void FaultInjector::release_delayed() {
  const int64_t now = steady_now_ns();
  while (!delayed_.empty() && delayed_.top().due_ns <= now) {
    const Delayed& next = delayed_.top();
    sender_.send(next.destination, next.port, next.bytes);
    delayed_.pop();
  }
  arm_delay_timer();
}

bool FaultInjector::frame_finished(uint64_t frame) {
  if (halted_ || !active()) return false;
  ++frames_under_plan_;
  const std::optional<SensorFaultEvent> fault = due_sensor_fault(frame);
  if (!fault) return false;
  halted_ = true;
  end_session();
  on_sensor_fault_(*fault);
  return true;
}

// The earliest event whose frame has come, once per plan.
std::optional<SensorFaultEvent> FaultInjector::due_sensor_fault(uint64_t frame) {
  const auto due = [this](const std::optional<double>& at_s, bool fired) {
    return at_s && !fired && frames_under_plan_ >= static_cast<uint64_t>(std::llround(*at_s * fps_));
  };
  // The last frame sent whole: a client sees its packets, then none of this init_id.
  json where{{"init_id", init_id_}, {"frames_streamed", frames_under_plan_}, {"last_frame", frame}};
  if (format_) where["last_frame_id"] = frame_id_of(frame + frame_offset_, format_->format());
  if (due(plan_.reset_at, reset_fired_)) {
    reset_fired_ = true;
    control_->record("reset", where);
    return SensorFaultEvent::kReset;
  }
  if (due(plan_.standby_at, standby_fired_)) {
    standby_fired_ = true;
    where["for_s"] = plan_.standby_for;
    control_->record("standby", where);
    return SensorFaultEvent::kStandby;
  }
  if (due(plan_.error_at, error_fired_)) {
    error_fired_ = true;
    where["for_s"] = plan_.error_for;
    control_->record("error", where);
    return SensorFaultEvent::kError;
  }
  return std::nullopt;
}

}  // namespace lidartwin::streamer_detail
