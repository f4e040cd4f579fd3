#include "streamer/background_jobs.h"

#include <pthread.h>
#include <sched.h>

#include <spdlog/spdlog.h>

#include "lidartwin/frame/worker_pool.h"

namespace lidartwin::streamer_detail {

BackgroundJobs::BackgroundJobs(int nice) : thread_([this, nice](std::stop_token stop) { run(stop, nice); }) {}

BackgroundJobs::~BackgroundJobs() {
  thread_.request_stop();
  wake_.notify_all();
}

void BackgroundJobs::post(std::function<void()> job) {
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  wake_.notify_one();
}

namespace {
// The lowest real-time priority, below the send clock's (serve_command.cpp): a session is built
// within its start delay even on a host whose casting keeps every core busy, and the send clocks
// still preempt it. Without CAP_SYS_NICE, the casting threads' nice value.
void run_below_send_clock(int nice) {
  sched_param param{};
  param.sched_priority = 1;
  if (pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) != 0) run_at_normal_priority(nice);
}
}  // namespace

void BackgroundJobs::run(const std::stop_token& stop, int nice) {
  run_below_send_clock(nice);
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, stop, [this] { return !jobs_.empty(); });
    if (jobs_.empty()) return;  // stopping, and nothing left to do
    std::function<void()> job = std::move(jobs_.front());
    jobs_.pop_front();
    lock.unlock();
    try {
      job();
    } catch (const std::exception& e) {
      spdlog::error("streamer: a background job failed: {}", e.what());
    }
    job = nullptr;  // what it held goes here, off the io thread
    lock.lock();
  }
}

}  // namespace lidartwin::streamer_detail
