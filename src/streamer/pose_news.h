#pragma once
// Wakes a render worker when a live pose arrives: the pose receiver's thread calls arrived(), and a
// paced worker waiting for its next packet's cast time wakes at once to cast again, with the new
// pose, the packets it cast before it that are not yet due (render_ahead.h).
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>

namespace lidartwin::streamer_detail {

class PoseNews {
 public:
  // Any thread.
  void arrived() {
    {
      std::lock_guard lock(mutex_);
      ++count_;
    }
    changed_.notify_all();
  }
  // Any thread: every waiter rechecks its stop condition (which the caller set before).
  void interrupt() {
    { std::lock_guard lock(mutex_); }
    changed_.notify_all();
  }
  uint64_t count() const {
    std::lock_guard lock(mutex_);
    return count_;
  }
  // Returns at steady_ns (the steady clock), once count() is past `seen`, or once stop() holds.
  template <typename Stop>
  void wait_until(int64_t steady_ns, uint64_t seen, Stop stop) {
    std::unique_lock lock(mutex_);
    const auto deadline = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(steady_ns));
    changed_.wait_until(lock, deadline, [&] { return count_ != seen || stop(); });
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  uint64_t count_ = 0;  // guarded by mutex_
};

}  // namespace lidartwin::streamer_detail
