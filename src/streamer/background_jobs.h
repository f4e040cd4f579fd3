#pragma once
// A streamer's sessions are built and retired on a thread of their own, not on the io thread that
// runs the send clock: a session's forward model and render buffers take tens of milliseconds to
// allocate and fault in (measured: 40 ms for an OS1-64 at 1024x10 on a 2-core VM), and its render
// worker must be joined when it ends. On the io thread either would hold up every packet due
// meanwhile, and a rig's io thread sends for all its sensors: one sensor's reinit would make the
// others' packets late. Jobs run in the order posted; the destructor runs what is queued and joins.
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <stop_token>
#include <thread>

namespace lidartwin::streamer_detail {

class BackgroundJobs {
 public:
  explicit BackgroundJobs(int nice);
  ~BackgroundJobs();
  BackgroundJobs(const BackgroundJobs&) = delete;
  BackgroundJobs& operator=(const BackgroundJobs&) = delete;

  void post(std::function<void()> job);

 private:
  void run(const std::stop_token& stop, int nice);

  std::mutex mutex_;
  std::condition_variable_any wake_;
  std::deque<std::function<void()>> jobs_;  // guarded by mutex_
  std::jthread thread_;                     // last: joined before the members above go
};

}  // namespace lidartwin::streamer_detail
