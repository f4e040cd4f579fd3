#pragma once
// The HTTP server's threads: httplib gives each connection to one thread for as long as the client
// keeps it alive, so a fixed pool of N threads serves N clients and the N+1st waits until one of
// them goes quiet for the keep-alive time-out (50 keep-alive clients on 8 threads: p75 0.64 s, p99
// 1.8 s). Here a connection that finds no idle thread starts one, up to a cap; a thread idle for
// `idle_exit` ends, so an idle daemon keeps few threads.
#include <httplib.h>

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>

namespace lidartwin::http_detail {

class ConnectionThreads : public httplib::TaskQueue {
 public:
  ConnectionThreads(std::size_t max_threads, std::chrono::milliseconds idle_exit);
  ~ConnectionThreads() override;  // shutdown()

  void enqueue(std::function<void()> connection) override;
  // Serves what is queued, then waits for every thread to end.
  void shutdown() override;

  std::size_t threads() const;  // running now

 private:
  void serve();

  const std::size_t max_threads_;
  const std::chrono::milliseconds idle_exit_;
  mutable std::mutex mutex_;
  std::condition_variable work_;
  std::condition_variable ended_;
  std::deque<std::function<void()>> queue_;
  std::size_t threads_ = 0;
  std::size_t idle_ = 0;
  bool shutdown_ = false;
};

}  // namespace lidartwin::http_detail
