#pragma once
// The sensor's HTTP server (cpp-httplib): keep-alive, timeouts, a body size limit, both request
// line forms (protocol doc 2.1), every request handed to RequestHandler.
#include <chrono>
#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>

#include "lidartwin/fault/fault_control.h"
#include "lidartwin/http_api/request_handler.h"
#include "lidartwin/sensor/sensor.h"

namespace lidartwin {

struct HttpServerOptions {
  std::string address = "127.0.0.1";     // one sensor per loopback address (DESIGN.md)
  int port = 80;                         // as on a real sensor; 0 = any free port
  std::size_t max_body_bytes = 1 << 20;  // a full config is ~1.5 KB (protocol doc 2.1)
  std::chrono::seconds read_timeout{5};
  std::chrono::seconds write_timeout{5};
  // curl reuses one connection (protocol doc 2.1); an idle one holds its thread this long.
  std::chrono::seconds keep_alive_timeout{5};
  std::size_t keep_alive_max_requests = 1000;
  // Connections served at once, each on a thread of its own that starts when a connection finds
  // none idle and ends after 10 s idle; past this many, a connection waits for one to close.
  std::size_t max_connections = 256;
  // At most this many of them from one address at once (the next is answered 503), and each is
  // shut down when it has not completed a request within request_deadline of opening or of its
  // last request: a slow client (slowloris) cannot hold the API away from the others.
  std::size_t max_connections_per_peer = 64;
  std::chrono::milliseconds request_deadline{10'000};
  // lidartwin's own endpoints (below /lidartwin/v1/, not part of the sensor's API), if any.
  ExtensionEndpoint lidartwin_api = nullptr;
  // The plan's HTTP faults (http_500, http_delay_ms) for requests below /api/v1/; null: none. Must
  // outlive the server.
  FaultControl* faults = nullptr;
  // A rig's sensor name: its log lines read "HTTP (roof): ..." (empty: a lone sensor's).
  std::string name = {};
};

// start() could not bind. The message explains what to do (for ports below 1024 the remedies of
// protocol doc 2.1); error_number() is the errno of bind().
class BindError : public std::runtime_error {
 public:
  BindError(const std::string& message, int error_number) : std::runtime_error(message), error_number_(error_number) {}
  int error_number() const { return error_number_; }

 private:
  int error_number_;
};

// The message of a BindError for bind()'s errno on address:port.
std::string describe_bind_error(const std::string& address, int port, int error_number);

class HttpServer {
 public:
  // `sensor` must outlive the server.
  HttpServer(Sensor& sensor, HttpServerOptions options);
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;
  ~HttpServer();  // stop()

  // Binds (throws BindError), then serves on a background thread until stop(). Once.
  void start();
  // Stops accepting, finishes requests in progress, joins. Idempotent. An idle keep-alive
  // connection can delay it by up to keep_alive_timeout.
  void stop();
  int port() const;  // the bound port (useful with port 0), after start()
  const std::string& address() const;

 private:
  struct Impl;  // keeps <httplib.h> out of this header
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
