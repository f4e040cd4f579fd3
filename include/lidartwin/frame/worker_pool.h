#pragma once
// The render workers: the caller and threads-1 workers drain a shared counter of work items. Which
// thread runs an item never changes its result (items write disjoint outputs, noise is keyed by
// pixel), so the thread count is free. One pool serves every sensor of a process (a rig): runs
// from several callers take turns, each a packet-sized chunk of work.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <stop_token>
#include <thread>
#include <utility>
#include <vector>

namespace lidartwin {

// Leaves any real-time scheduling policy the calling thread inherited and sets its nice value.
void run_at_normal_priority(int nice);

class WorkerPool {
 public:
  // threads: total including the calling thread; 0 = std::thread::hardware_concurrency().
  // The workers leave any real-time policy they inherit (the daemon's send clock may run as
  // SCHED_FIFO and must win the CPU from casting) and run at the given nice value.
  explicit WorkerPool(int threads, int nice = 0);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int size() const { return static_cast<int>(threads_.size()) + 1; }
  // Calls task(worker, item) once for every item in [0, count), worker in [0, size()); returns when
  // all are done. One run at a time (later callers wait); the first exception is rethrown.
  void run(int count, const std::function<void(int worker, int item)>& task);

 private:
  void worker_loop(const std::stop_token& stop, int worker);
  void drain(int worker);

  std::mutex run_mutex_;
  std::mutex mutex_;
  std::condition_variable_any wake_;
  std::condition_variable done_;
  const std::function<void(int, int)>* task_ = nullptr;
  int count_ = 0;
  std::atomic<int> next_{0};
  int busy_ = 0;
  uint64_t generation_ = 0;
  std::exception_ptr error_;
  std::vector<std::jthread> threads_;  // last: stopped and joined before the members above go
};

}  // namespace lidartwin
