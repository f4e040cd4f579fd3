#include "http_api/connection_guard.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

namespace lidartwin::http_detail {
namespace {

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string peer_of(int sock) {
  sockaddr_storage address{};
  socklen_t length = sizeof address;
  if (::getpeername(sock, reinterpret_cast<sockaddr*>(&address), &length) != 0) return "?";
  char text[INET6_ADDRSTRLEN] = {};
  if (address.ss_family == AF_INET) {
    ::inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(&address)->sin_addr, text, sizeof text);
  } else if (address.ss_family == AF_INET6) {
    ::inet_ntop(AF_INET6, &reinterpret_cast<sockaddr_in6*>(&address)->sin6_addr, text, sizeof text);
  }
  return text;
}

// The connection served on this thread (each connection has a thread of its own while it is open).
struct Current {
  ConnectionGuard* guard = nullptr;
  uint64_t id = 0;
};
thread_local Current current;
// Set by request_answered() through the guard's lock.
thread_local int64_t* current_deadline = nullptr;

}  // namespace

ConnectionGuard::ConnectionGuard(Options options) : options_(options), watchdog_([this] { watch(); }) {}

ConnectionGuard::~ConnectionGuard() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  stop_.notify_all();
  watchdog_.join();
}

bool ConnectionGuard::enter(int sock) {
  std::string peer = peer_of(sock);
  std::unique_lock lock(mutex_);
  std::size_t& held = per_peer_[peer];
  if (held >= options_.max_per_peer) {
    ++counts_.refused;
    lock.unlock();
    answer_busy(sock, peer);
    return false;
  }
  ++held;
  const uint64_t id = next_id_++;
  Connection& connection = connections_[id];
  connection.peer = std::move(peer);
  connection.watch_fd = ::dup(sock);
  connection.deadline_ns = now_ns() + std::chrono::nanoseconds(options_.request_deadline).count();
  current = {this, id};
  current_deadline = &connection.deadline_ns;
  return true;
}

void ConnectionGuard::leave() {
  std::lock_guard lock(mutex_);
  const auto it = connections_.find(current.id);
  if (current.guard == this && it != connections_.end()) {
    if (it->second.watch_fd >= 0) ::close(it->second.watch_fd);
    if (--per_peer_[it->second.peer] == 0) per_peer_.erase(it->second.peer);
    connections_.erase(it);
  }
  current = {};
  current_deadline = nullptr;
}

void ConnectionGuard::request_answered() {
  if (!current.guard) return;
  std::lock_guard lock(current.guard->mutex_);
  if (current_deadline) {
    *current_deadline = now_ns() + std::chrono::nanoseconds(current.guard->options_.request_deadline).count();
  }
}

ConnectionGuard::Counts ConnectionGuard::counts() const {
  std::lock_guard lock(mutex_);
  Counts counts = counts_;
  counts.open = connections_.size();
  return counts;
}

// A minimal answer, so a client over the cap learns why instead of seeing a reset.
void ConnectionGuard::answer_busy(int sock, const std::string& peer) {
  const std::string body = "{\"error\":\"too many connections from " + peer + " (at most " +
                           std::to_string(options_.max_per_peer) + " at once)\"}";
  const std::string response =
      "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nContent-Length: " +
      std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body;
  [[maybe_unused]] const ssize_t sent = ::send(sock, response.data(), response.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

// Four times a second: connections past their deadline are shut down (their thread's read returns
// at once and httplib closes them), and new refusals and cuts are logged.
void ConnectionGuard::watch() {
  std::unique_lock lock(mutex_);
  while (!stop_.wait_for(lock, std::chrono::milliseconds(250), [this] { return stopping_; })) {
    const int64_t now = now_ns();
    for (auto& [id, connection] : connections_) {
      if (connection.cut || now < connection.deadline_ns) continue;
      connection.cut = true;
      ++counts_.cut;
      ::shutdown(connection.watch_fd, SHUT_RDWR);
    }
    if (counts_.refused > logged_refused_ || counts_.cut > logged_cut_) {
      spdlog::warn(
          "HTTP{}: {} connections refused (over {} from one address) and {} cut (no request completed in {} "
          "s) since the last report; {} open",
          options_.log_tag, counts_.refused - logged_refused_, options_.max_per_peer, counts_.cut - logged_cut_,
          std::chrono::duration<double>(options_.request_deadline).count(), connections_.size());
      logged_refused_ = counts_.refused;
      logged_cut_ = counts_.cut;
    }
  }
}

}  // namespace lidartwin::http_detail
