// Live poses over UDP and the stream's watchdog (include/lidartwin/rig/pose_receiver.h).
#include "lidartwin/rig/pose_receiver.h"

#include <chrono>

#include <spdlog/spdlog.h>

#include "lidartwin/error.h"

namespace lidartwin {
namespace {

constexpr auto kWatchdogPeriod = std::chrono::milliseconds(20);
constexpr int64_t kWaitingNoticeNs = 5'000'000'000;  // "no pose yet" after this long
constexpr uint64_t kRejectionsLoggedOneByOne = 5;
constexpr int64_t kRejectionSummaryNs = 5'000'000'000;

}  // namespace

PoseReceiver::PoseReceiver(asio::io_context& io, LivePoses& poses, std::optional<asio::ip::udp::endpoint> listen,
                           asio::ip::address_v4 interface)
    : io_(io), poses_(poses), watchdog_(io) {
  if (!listen) return;
  socket_.emplace(io);
  const bool multicast = listen->address().is_multicast();
  asio::error_code error;
  socket_->open(listen->protocol(), error);
  // The sensors of a rig on one host each join the group on the same port.
  if (!error && multicast) socket_->set_option(asio::socket_base::reuse_address(true), error);
  if (!error) socket_->bind(*listen, error);  // bound to the group: only its datagrams arrive
  const std::string where = "--pose-udp " + listen->address().to_string() + ":" + std::to_string(listen->port());
  if (error) throw InputError(where + ": cannot listen for pose messages there: " + error.message());
  if (multicast) {
    socket_->set_option(asio::ip::multicast::join_group(listen->address().to_v4(), interface), error);
    if (error) {
      throw InputError(where + ": cannot join the multicast group on " +
                       (interface.is_unspecified() ? std::string("the default interface") : interface.to_string()) +
                       ": " + error.message() +
                       " (is there a multicast route? e.g. ip route add 224.0.0.0/4 dev eth0)");
    }
    joined_ = interface.is_unspecified() ? "the default interface" : interface.to_string();
  }
}

PoseReceiver::~PoseReceiver() = default;

void PoseReceiver::start() {
  started_ns_ = host_steady_ns();
  if (socket_) {
    spdlog::info("live poses: listening on udp {}:{}{} (clock {}, extrapolating up to {:.0f} ms, then {})",
                 socket_->local_endpoint().address().to_string(), port(),
                 joined_.empty() ? "" : ", the multicast group joined on " + joined_, to_string(poses_.options().clock),
                 poses_.options().max_extrapolation_s * 1e3, to_string(poses_.options().timeout));
    receive_next();
  }
  arm_watchdog();
}

void PoseReceiver::stop() {
  stopped_ = true;
  watchdog_.cancel();
  if (socket_) {
    asio::error_code ignored;
    socket_->close(ignored);
  }
}

uint16_t PoseReceiver::port() const { return socket_ ? socket_->local_endpoint().port() : 0; }

void PoseReceiver::receive_next() {
  socket_->async_receive_from(asio::buffer(buffer_), sender_, [this](const asio::error_code& error, size_t size) {
    if (stopped_ || error == asio::error::operation_aborted) return;
    if (!error) on_datagram(size);
    receive_next();
  });
}

void PoseReceiver::on_datagram(size_t size) {
  const int64_t arrival = host_steady_ns();
  try {
    poses_.receive(decode_pose_message({buffer_.data(), size}), arrival);
  } catch (const PoseRejected& e) {
    if (e.reason() != PoseRejection::kTimeBackwards) poses_.count_rejection(e.reason());  // receive() counts that one
    log_rejection(std::string(e.what()) + " (from " + sender_.address().to_string() + ")");
  }
}

// One line per refused message for the first few, then a count at most every few seconds: a
// misconfigured sender at 1 kHz must not flood the log, but no refusal goes unmentioned.
void PoseReceiver::log_rejection(const std::string& message) {
  if (++logged_rejections_ <= kRejectionsLoggedOneByOne) {
    spdlog::warn("live poses: refused {}", message);
    reported_rejections_ = logged_rejections_;
    return;
  }
  const int64_t now = host_steady_ns();
  if (now - last_summary_ns_ < kRejectionSummaryNs) return;
  spdlog::warn("live poses: refused {} more messages (latest: {}); GET /lidartwin/v1/pose counts them by reason",
               logged_rejections_ - reported_rejections_, message);
  reported_rejections_ = logged_rejections_;
  last_summary_ns_ = now;
}

void PoseReceiver::arm_watchdog() {
  watchdog_.expires_after(kWatchdogPeriod);
  watchdog_.async_wait([this](const asio::error_code& error) {
    if (error || stopped_) return;
    check_stream();
    arm_watchdog();
  });
}

void PoseReceiver::check_stream() {
  const LivePoseStats stats = poses_.stats();
  const int64_t now = host_steady_ns();
  if (!stats.newest) {
    if (!waiting_logged_ && now - started_ns_ > kWaitingNoticeNs) {
      spdlog::warn("live poses: none received yet; until one arrives no column has a pose ({})",
                   to_string(poses_.options().timeout));
      waiting_logged_ = true;
    }
    return;
  }
  const double age_s = static_cast<double>(now - stats.newest_arrival_steady_ns) * 1e-9;
  const double limit_s = poses_.options().max_extrapolation_s;
  if (!stalled_ && age_s > limit_s) {
    stalled_ = true;
    spdlog::warn(
        "live poses: stream stalled: no pose for {:.0f} ms (newest: sequence {}); past {:.0f} ms of "
        "extrapolation the sensor's columns are {}",
        age_s * 1e3, stats.newest->sequence, limit_s * 1e3,
        poses_.options().timeout == PoseTimeout::kHold      ? "cast from the held pose"
        : poses_.options().timeout == PoseTimeout::kInvalid ? "sent invalid (status 0)"
                                                            : "not sent (standby)");
  } else if (stalled_ && stats.accepted > seen_accepted_ && age_s <= limit_s) {
    stalled_ = false;
    spdlog::info("live poses: stream resumed (sequence {})", stats.newest->sequence);
  }
  if (seen_accepted_ == 0) spdlog::info("live poses: first pose received (sequence {})", stats.newest->sequence);
  seen_accepted_ = stats.accepted;
}

}  // namespace lidartwin
