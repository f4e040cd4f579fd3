#pragma once
// Bytes over a plain TCP socket, for what an HTTP client library will not send: absolute-form
// request lines (HTTP proxy, protocol doc 2.1), chunked or malformed requests, several requests on
// one connection.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <stdexcept>
#include <string>
#include <utility>

namespace lidartwin::test {

class RawConnection {
 public:
  explicit RawConnection(int port) : sock_(::socket(AF_INET, SOCK_STREAM, 0)) {
    if (sock_ < 0) throw std::runtime_error("socket");
    timeval timeout{5, 0};
    ::setsockopt(sock_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(sock_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
      ::close(sock_);
      throw std::runtime_error("connect");
    }
  }
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;
  ~RawConnection() { ::close(sock_); }

  void send(const std::string& bytes) {
    for (size_t sent = 0; sent < bytes.size();) {
      const auto n = ::send(sock_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return;  // the server may close early (e.g. after refusing the request)
      sent += static_cast<size_t>(n);
    }
  }

  // Everything until the server closes the connection (or 5 s pass).
  std::string read_all() {
    while (fill()) {
    }
    return std::exchange(pending_, "");
  }

  // One response: status line, headers and a Content-Length body; "" on timeout or close.
  std::string read_response() {
    size_t header_end;
    while ((header_end = pending_.find("\r\n\r\n")) == std::string::npos) {
      if (!fill()) return "";
    }
    size_t length = 0;
    for (size_t line = pending_.find("\r\n"); line < header_end; line = pending_.find("\r\n", line + 2)) {
      if (strncasecmp(pending_.c_str() + line + 2, "Content-Length:", 15) == 0) {
        length = std::stoul(pending_.substr(line + 17));
      }
    }
    while (pending_.size() < header_end + 4 + length) {
      if (!fill()) return "";
    }
    const std::string response = pending_.substr(0, header_end + 4 + length);
    pending_.erase(0, response.size());
    return response;
  }

 private:
  bool fill() {
    char buffer[4096];
    const auto n = ::recv(sock_, buffer, sizeof buffer, 0);
    if (n <= 0) return false;
    pending_.append(buffer, static_cast<size_t>(n));
    return true;
  }

  int sock_;
  std::string pending_;
};

// Sends `request` to 127.0.0.1:port and returns all bytes received until the server closes the
// connection (so the request should say "Connection: close").
inline std::string raw_exchange(int port, const std::string& request) {
  RawConnection connection(port);
  connection.send(request);
  return connection.read_all();
}

// The body of the last response in `received` (after its blank line).
inline std::string last_body(const std::string& received) {
  const auto start = received.rfind("\r\n\r\n");
  return start == std::string::npos ? "" : received.substr(start + 4);
}

}  // namespace lidartwin::test
