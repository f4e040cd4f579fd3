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

WorkerPool::Run* WorkerPool::open_run_locked() const {
  for (Run* run : runs_) {
    if (run->next.load(std::memory_order_relaxed) < run->count) return run;
  }
  return nullptr;
}

void WorkerPool::drain(Run& run, int worker) {
  for (int item = run.next.fetch_add(1); item < run.count; item = run.next.fetch_add(1)) {
    try {
      (*run.task)(worker, item);
    } catch (...) {
      std::lock_guard lock(mutex_);
      if (!run.error) run.error = std::current_exception();
      run.next.store(run.count);  // skip the remaining items
    }
  }
}

// Oldest run first, so that every caller's run is helped in turn (a rig's sensors alike).
void WorkerPool::worker_loop(const std::stop_token& stop, int worker) {
  std::unique_lock lock(mutex_);
  for (;;) {
    Run* run = open_run_locked();
    if (!run) {
      ++idle_;
      const bool woken = wake_.wait(lock, stop, [&] { return (run = open_run_locked()) != nullptr; });
      --idle_;
      if (!woken) return;
    }
    ++run->helpers;
    lock.unlock();
    drain(*run, worker);
    lock.lock();
    if (--run->helpers == 0) done_.notify_all();
  }
}

void WorkerPool::run(int count, const std::function<void(int worker, int item)>& task) {
  if (threads_.empty() || count <= 1) {
    for (int item = 0; item < count; ++item) task(0, item);
    return;
  }
  Run run;
  run.task = &task;
  run.count = count;
  int wake = 0;
  {
    std::lock_guard lock(mutex_);
    runs_.push_back(&run);
    // Workers are woken only where a core would otherwise idle: callers already running as many
    // runs as the pool has threads keep the cores busy themselves, and every wake-up costs CPU.
    wake = std::min({idle_, count - 1, size() - static_cast<int>(runs_.size())});
  }
  for (int i = 0; i < wake; ++i) wake_.notify_one();
  drain(run, 0);
  std::unique_lock lock(mutex_);
  runs_.erase(std::find(runs_.begin(), runs_.end(), &run));  // no worker joins it from here
  done_.wait(lock, [&] { return run.helpers == 0; });        // only those that started on it
  if (run.error) std::rethrow_exception(run.error);
}

std::vector<WorkPiece> guided_pieces(int count, int workers) {
  std::vector<WorkPiece> pieces;
  for (int first = 0; first < count;) {
    const int size = std::max(1, (count - first) / (2 * std::max(1, workers)));
    pieces.push_back({first, size});
    first += size;
  }
  return pieces;
}

}  // namespace lidartwin
