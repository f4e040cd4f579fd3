#pragma once
// Slow and greedy clients (slowloris): every connection holds one of the server's
// threads for as long as it is open, so a client that opens many, or dribbles a request's headers
// a byte at a time, could take every thread and lock the sensor's API away from everyone else.
// The guard caps the connections one peer address holds at once (the one over the cap is answered
// 503 and closed), and shuts a connection down when it has not completed a request within
// `request_deadline` of opening or of its last one (a keep-alive connection that is merely idle is
// closed by httplib sooner, after its keep-alive time-out).
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <thread>

namespace lidartwin::http_detail {

class ConnectionGuard {
 public:
  struct Options {
    std::size_t max_per_peer = 64;
    std::chrono::milliseconds request_deadline{10'000};
    std::string log_tag = {};  // after "HTTP" in its reports (log_tag.h)
  };
  explicit ConnectionGuard(Options options);
  ~ConnectionGuard();  // stops the watchdog
  ConnectionGuard(const ConnectionGuard&) = delete;
  ConnectionGuard& operator=(const ConnectionGuard&) = delete;

  // On the connection's own thread, before it is served. False when its peer already holds
  // max_per_peer connections: the client has been answered 503, and the caller closes the socket.
  bool enter(int sock);
  // On the same thread, after the connection was served and closed.
  void leave();
  // A request on the calling thread's connection was answered: its deadline starts again.
  static void request_answered();

  struct Counts {
    uint64_t refused = 0;  // over the per-peer cap
    uint64_t cut = 0;      // past the request deadline
    std::size_t open = 0;
  };
  Counts counts() const;

 private:
  struct Connection {
    std::string peer;
    int watch_fd = -1;  // a dup of the socket: the watchdog's shutdown() never hits a reused number
    int64_t deadline_ns = 0;
    bool cut = false;
  };
  void watch();
  void answer_busy(int sock, const std::string& peer);

  const Options options_;
  mutable std::mutex mutex_;
  std::condition_variable stop_;
  bool stopping_ = false;
  std::map<uint64_t, Connection> connections_;  // by id
  std::map<std::string, std::size_t> per_peer_;
  uint64_t next_id_ = 0;
  Counts counts_;
  uint64_t logged_refused_ = 0, logged_cut_ = 0;
  std::thread watchdog_;  // last: starts when everything it reads exists
};

}  // namespace lidartwin::http_detail
