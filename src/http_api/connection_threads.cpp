#include "http_api/connection_threads.h"

#include <thread>
#include <utility>

#include <sys/resource.h>
#include <unistd.h>

namespace lidartwin::http_detail {
namespace {
constexpr int kNice = 10;
}  // namespace

ConnectionThreads::ConnectionThreads(std::size_t max_threads, std::chrono::milliseconds idle_exit)
    : max_threads_(max_threads == 0 ? 1 : max_threads), idle_exit_(idle_exit) {}

ConnectionThreads::~ConnectionThreads() { shutdown(); }

void ConnectionThreads::enqueue(std::function<void()> connection) {
  std::lock_guard lock(mutex_);
  queue_.push_back(std::move(connection));
  // An idle thread takes it; otherwise one more starts, while under the cap (past it, the
  // connection waits for the first thread to come free, as with a fixed pool).
  if (idle_ >= queue_.size()) {
    work_.notify_one();
  } else if (threads_ < max_threads_) {
    ++threads_;
    // Detached: a thread that ends on its own leaves nothing to join; shutdown() waits on the count.
    std::thread([this] { serve(); }).detach();
  }
}

void ConnectionThreads::serve() {
  // Below the stream: a sensor's lidar data comes before its web server. At equal priority, 50
  // keep-alive clients asking for the metadata left 85 % of an OS1-128 2048x10 stream's packets
  // un-rendered on two cores; at nice 10 a busy HTTP thread gets a tenth of a rendering one's share.
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), kNice);
  std::unique_lock lock(mutex_);
  for (;;) {
    ++idle_;
    const bool woken = work_.wait_for(lock, idle_exit_, [this] { return !queue_.empty() || shutdown_; });
    --idle_;
    if (queue_.empty()) {
      if (shutdown_ || !woken) break;
      continue;
    }
    std::function<void()> connection = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    connection();
    connection = nullptr;  // its captures (the socket's state) go before the count does
    lock.lock();
  }
  --threads_;
  ended_.notify_all();
}

void ConnectionThreads::shutdown() {
  std::unique_lock lock(mutex_);
  shutdown_ = true;
  work_.notify_all();
  // Queued connections are still served: a thread is running for each while the cap allows, and
  // the running ones take the rest before they see the queue empty.
  ended_.wait(lock, [this] { return threads_ == 0; });
}

std::size_t ConnectionThreads::threads() const {
  std::lock_guard lock(mutex_);
  return threads_;
}

}  // namespace lidartwin::http_detail
