#include "lidartwin/frame/worker_pool.h"

#include <algorithm>

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

namespace lidartwin {

void run_at_normal_priority(int nice) {
  const sched_param normal{};
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice);  // per thread on Linux
}

WorkerPool::WorkerPool(int threads, int nice) {
  const int total = threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  for (int worker = 1; worker < total; ++worker) {
    threads_.emplace_back([this, worker, nice](std::stop_token stop) {
      run_at_normal_priority(nice);
      worker_loop(stop, worker);
    });
  }
}

WorkerPool::~WorkerPool() {
  for (auto& thread : threads_) thread.request_stop();
  wake_.notify_all();
  threads_.clear();  // joins
}

void WorkerPool::drain(int worker) {
  for (int item = next_.fetch_add(1); item < count_; item = next_.fetch_add(1)) {
    try {
      (*task_)(worker, item);
    } catch (...) {
      std::lock_guard lock(mutex_);
      if (!error_) error_ = std::current_exception();
      next_.store(count_);  // skip the remaining items
    }
  }
}

void WorkerPool::worker_loop(const std::stop_token& stop, int worker) {
  uint64_t seen = 0;
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      if (!wake_.wait(lock, stop, [&] { return generation_ != seen; })) return;
      seen = generation_;
    }
    drain(worker);
    std::lock_guard lock(mutex_);
    if (--busy_ == 0) done_.notify_all();
  }
}

void WorkerPool::run(int count, const std::function<void(int worker, int item)>& task) {
  std::lock_guard run_lock(run_mutex_);
  if (threads_.empty() || count <= 1) {
    for (int item = 0; item < count; ++item) task(0, item);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    task_ = &task;
    count_ = count;
    next_.store(0);
    busy_ = static_cast<int>(threads_.size());
    error_ = nullptr;
    ++generation_;
  }
  wake_.notify_all();
  drain(0);
  std::unique_lock lock(mutex_);
  done_.wait(lock, [&] { return busy_ == 0; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

}  // namespace lidartwin
