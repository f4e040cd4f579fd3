// Live poses: a short history of received poses, answered by interpolation and bounded
// extrapolation (include/lidartwin/pose/live_poses.h).
#include "lidartwin/pose/live_poses.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>

namespace lidartwin {
namespace {

constexpr int64_t kTaiMinusUtcNs = 37'000'000'000;  // leap seconds since 2017
// Differencing the two newest poses for a velocity only when they are this close in time.
constexpr double kMaxDifferenceGapS = 1.0;

int64_t clock_ns(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

Pose interpolate(const Pose& a, const Pose& b, double fraction) {
  return {a.rotation.slerp(fraction, b.rotation), a.translation + fraction * (b.translation - a.translation)};
}

Eigen::Quaterniond rotation_by(const Eigen::Vector3d& angle_axis) {
  const double angle = angle_axis.norm();
  if (angle < 1e-15) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, angle_axis / angle));
}

template <typename Enum, size_t N>
std::optional<Enum> parse_name(std::string_view name, const std::array<Enum, N>& values) {
  for (Enum value : values) {
    if (name == to_string(value)) return value;
  }
  return std::nullopt;
}

}  // namespace

const char* to_string(PoseClock clock) {
  switch (clock) {
    case PoseClock::kSender: return "sender";
    case PoseClock::kMonotonic: return "monotonic";
    case PoseClock::kRealtime: return "realtime";
    case PoseClock::kTai: return "tai";
    case PoseClock::kSimulation: return "simulation";
  }
  return "unknown";
}

const char* to_string(PoseTimeout timeout) {
  switch (timeout) {
    case PoseTimeout::kHold: return "hold";
    case PoseTimeout::kInvalid: return "invalid";
    case PoseTimeout::kStandby: return "standby";
  }
  return "unknown";
}

std::optional<PoseClock> parse_pose_clock(std::string_view name) {
  return parse_name(name, std::array{PoseClock::kSender, PoseClock::kMonotonic, PoseClock::kRealtime, PoseClock::kTai});
}

std::optional<PoseTimeout> parse_pose_timeout(std::string_view name) {
  return parse_name(name, std::array{PoseTimeout::kHold, PoseTimeout::kInvalid, PoseTimeout::kStandby});
}

int64_t host_steady_ns() { return clock_ns(CLOCK_MONOTONIC); }

uint64_t LivePoseStats::rejected_total() const {
  uint64_t total = 0;
  for (uint64_t n : rejected) total += n;
  return total;
}

LivePoses::LivePoses(LivePoseOptions options, int64_t epoch_steady_ns)
    : options_(options), epoch_steady_ns_(epoch_steady_ns) {}

// Host steady clock minus the message clock, as of this message.
int64_t LivePoses::offset_ns_locked(int64_t arrival_steady_ns, int64_t message_ns) {
  switch (options_.clock) {
    case PoseClock::kMonotonic:
    case PoseClock::kSimulation: return 0;
    case PoseClock::kRealtime: return host_steady_ns() - clock_ns(CLOCK_REALTIME);
    case PoseClock::kTai: return host_steady_ns() - clock_ns(CLOCK_REALTIME) - kTaiMinusUtcNs;
    case PoseClock::kSender: {
      // A message cannot arrive before it was sent: the smallest (arrival - time) seen is the
      // clock offset plus the fastest transit, the usual one-way estimate (no drift correction).
      const int64_t candidate = arrival_steady_ns - message_ns;
      if (!sender_offset_ns_ || candidate < *sender_offset_ns_) sender_offset_ns_ = candidate;
      return *sender_offset_ns_;
    }
  }
  return 0;
}

void LivePoses::receive(const PoseMessage& message, int64_t arrival_steady_ns) {
  add(message, arrival_steady_ns);
  std::lock_guard lock(listeners_mutex_);
  for (const auto& [id, listener] : listeners_) listener(message);
}

int LivePoses::subscribe(Listener listener) {
  std::lock_guard lock(listeners_mutex_);
  listeners_.emplace_back(next_listener_, std::move(listener));
  return next_listener_++;
}

void LivePoses::unsubscribe(int id) {
  std::lock_guard lock(listeners_mutex_);
  std::erase_if(listeners_, [id](const auto& entry) { return entry.first == id; });
}

void LivePoses::add(const PoseMessage& message, int64_t arrival_steady_ns) {
  std::lock_guard lock(mutex_);
  if (!samples_.empty() && message.time_ns <= samples_.back().time_ns) {
    ++stats_.rejected[static_cast<size_t>(PoseRejection::kTimeBackwards)];
    throw PoseRejected(PoseRejection::kTimeBackwards,
                       "pose message " + std::to_string(message.sequence) + ": time_ns " +
                           std::to_string(message.time_ns) + " is not after the newest pose's " +
                           std::to_string(samples_.back().time_ns) + " (late, repeated or out of order)");
  }
  if (stats_.newest && message.sequence > stats_.newest->sequence + 1) {
    stats_.lost += message.sequence - stats_.newest->sequence - 1;
  }
  stats_.clock_offset_ns = offset_ns_locked(arrival_steady_ns, message.time_ns);
  samples_.push_back({message.time_ns, message});
  const auto history_ns = static_cast<int64_t>(options_.history_s * 1e9);
  while (samples_.size() > 2 && samples_.front().time_ns < message.time_ns - history_ns) samples_.pop_front();
  ++stats_.accepted;
  stats_.newest = message;
  stats_.newest_arrival_steady_ns = arrival_steady_ns;
}

void LivePoses::count_rejection(PoseRejection reason) {
  std::lock_guard lock(mutex_);
  ++stats_.rejected[static_cast<size_t>(reason)];
}

double LivePoses::sample_time_s(const Sample& sample) const {
  return static_cast<double>(sample.time_ns + stats_.clock_offset_ns - epoch_steady_ns_) * 1e-9;
}

double LivePoses::source_time_s(int64_t steady_ns) const {
  return static_cast<double>(steady_ns - epoch_steady_ns_) * 1e-9;
}

int64_t LivePoses::steady_ns(double source_time_s) const {
  return epoch_steady_ns_ + static_cast<int64_t>(std::llround(source_time_s * 1e9));
}

// Constant velocity and angular rate from the newest pose: the message's own when it carries them,
// else differenced from the pose before it.
Pose LivePoses::extrapolate(double ahead_s) const {
  const Sample& newest = samples_.back();
  const PoseMessage& m = newest.message;
  Eigen::Vector3d velocity = m.velocity.value_or(Eigen::Vector3d::Zero());
  Eigen::Vector3d angular_rate = m.angular_rate.value_or(Eigen::Vector3d::Zero());
  if (samples_.size() >= 2 && (!m.velocity || !m.angular_rate)) {
    const Sample& before = samples_[samples_.size() - 2];
    const double gap_s = static_cast<double>(newest.time_ns - before.time_ns) * 1e-9;
    if (gap_s <= kMaxDifferenceGapS) {
      if (!m.velocity) velocity = (m.pose.translation - before.message.pose.translation) / gap_s;
      if (!m.angular_rate) {
        const Eigen::AngleAxisd step(before.message.pose.rotation.conjugate() * m.pose.rotation);
        angular_rate = step.axis() * (step.angle() / gap_s);
      }
    }
  }
  return {(m.pose.rotation * rotation_by(angular_rate * ahead_s)).normalized(),
          m.pose.translation + velocity * ahead_s};
}

Pose LivePoses::at(double time_s) const {
  std::lock_guard lock(mutex_);
  if (samples_.empty()) return {};
  const Sample& newest = samples_.back();
  const double after_newest_s = time_s - sample_time_s(newest);
  if (after_newest_s >= 0.0) return extrapolate(std::min(after_newest_s, options_.max_extrapolation_s));
  const auto later = std::upper_bound(samples_.begin(), samples_.end(), time_s,
                                      [this](double t, const Sample& s) { return t < sample_time_s(s); });
  if (later == samples_.begin()) return later->message.pose;
  const Sample& a = *(later - 1);
  const Sample& b = *later;
  const double fraction = (time_s - sample_time_s(a)) / (sample_time_s(b) - sample_time_s(a));
  return interpolate(a.message.pose, b.message.pose, std::clamp(fraction, 0.0, 1.0));
}

PoseSpan LivePoses::span() const {
  std::lock_guard lock(mutex_);
  if (samples_.empty()) {
    return {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  }
  PoseSpan span;
  span.begin_s = sample_time_s(samples_.front());
  span.end_s = options_.timeout == PoseTimeout::kHold ? std::numeric_limits<double>::infinity()
                                                      : sample_time_s(samples_.back()) + options_.max_extrapolation_s;
  return span;
}

PoseFreshness LivePoses::freshness() const {
  std::lock_guard lock(mutex_);
  return {stats_.accepted, stats_.newest_arrival_steady_ns};
}

LivePoseStats LivePoses::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace lidartwin
