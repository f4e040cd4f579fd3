// cpp-httplib wiring: every request goes through one catch-all handler per method into
// RequestHandler, which does the routing (so absolute-form paths, 404 vs 405 and the error bodies
// are ours, not httplib's). This file only moves bytes.
#include "lidartwin/http_api/http_server.h"

#include <httplib.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <optional>
#include <thread>

#include "http_api/api_util.h"
#include "http_api/bind_probe.h"
#include "http_api/connection_guard.h"
#include "http_api/connection_threads.h"
#include "lidartwin/fault/fault_schedule.h"
#include "lidartwin/http_api/request_handler.h"
#include "lidartwin/log_tag.h"

namespace lidartwin {
namespace {

ApiRequest to_api_request(const httplib::Request& request, std::string body) {
  ApiRequest api;
  api.method = request.method;
  api.path = request.path;
  api.query.insert(request.params.begin(), request.params.end());
  api.body = std::move(body);
  api.peer_ip = request.remote_addr;
  api.local_ip = request.local_addr;
  return api;
}

void write_response(const ApiResponse& api, httplib::Response& response) {
  response.status = api.status;
  for (const auto& [name, value] : api.headers) response.set_header(name.c_str(), value);
  response.set_content(api.body, "application/json");
}

// Reads the body, keeping at most `limit` bytes. A longer body is read to its end and dropped, so
// the connection stays usable; `too_large` tells. (httplib's own limit covers Content-Length
// bodies only, not chunked ones.)
bool read_body(const httplib::ContentReader& reader, std::size_t limit, std::string& body, bool& too_large) {
  return reader([&](const char* data, std::size_t size) {
    if (too_large || body.size() + size > limit) {
      too_large = true;
      body.clear();
    } else {
      body.append(data, size);
    }
    return true;
  });
}

std::string too_large_message(std::size_t limit) {
  return "request body too large: the limit is " + std::to_string(limit) + " bytes";
}

// Bodies for the errors httplib answers itself (413, a malformed request line, ...). Our own
// error responses already have one.
httplib::Server::HandlerResponse fill_error_body(httplib::Response& response, std::size_t limit) {
  if (!response.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
  std::string message = "HTTP error " + std::to_string(response.status);
  if (response.status == 413) message = too_large_message(limit);
  if (response.status == 414) message = "request line too long";
  if (response.status == 400) message = "malformed HTTP request";
  write_response(error_response(response.status, message), response);
  return httplib::Server::HandlerResponse::Handled;
}

// The plan's HTTP faults for one request of the sensor's API: answered late, or with a 500 as a
// sensor whose web server failed would, and logged with the request it hit.
std::optional<ApiResponse> injected_fault(FaultControl& faults, const ApiRequest& request) {
  const FaultPlan plan = faults.plan();
  if (plan.http_500 <= 0 && plan.http_delay_ms <= 0) return std::nullopt;
  const uint64_t sequence = faults.next_http_request();
  const HttpFate fate = http_fate(plan, sequence);
  if (fate.delay_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(fate.delay_ns));
  if (!fate.fail) return std::nullopt;
  faults.record("http_500", {{"method", request.method}, {"path", request.path}, {"request", sequence}});
  return error_response(500, "internal error (injected by lidartwin's fault plan: http_500)");
}

}  // namespace

namespace http_detail {

// httplib 0.11 serves each accepted connection in Server::process_and_close_socket, a private
// virtual function: overriding it is the one place the socket is in reach, to guard it. The
// library's own version (exported from libcpp-httplib) then serves it, called by its symbol,
// since C++ offers no other way to call a private base function.
extern "C" bool lidartwin_httplib_serve_connection(httplib::Server* server,
                                                   int sock) __asm__("_ZN7httplib6Server24process_and_close_socketEi");

class GuardedServer : public httplib::Server {
 public:
  explicit GuardedServer(ConnectionGuard::Options options) : guard_(std::move(options)) {}

 private:
  bool process_and_close_socket(socket_t sock) override {
    if (!guard_.enter(sock)) {
      ::shutdown(sock, SHUT_RDWR);
      ::close(sock);
      return false;
    }
    struct Leave {
      ConnectionGuard& guard;
      ~Leave() { guard.leave(); }
    } leave{guard_};
    return lidartwin_httplib_serve_connection(this, sock);
  }

  ConnectionGuard guard_;
};

}  // namespace http_detail

struct HttpServer::Impl {
  Impl(Sensor& sensor, HttpServerOptions server_options)
      : options(std::move(server_options)), handler(sensor, options.lidartwin_api, log_tag(options.name)) {}

  void configure();
  void configure_connections();
  void handle(const httplib::Request& request, httplib::Response& response, std::string body);
  void handle_with_body(const httplib::Request& request, httplib::Response& response,
                        const httplib::ContentReader& reader);

  HttpServerOptions options;
  RequestHandler handler;
  http_detail::GuardedServer server{
      {options.max_connections_per_peer, options.request_deadline, log_tag(options.name)}};
  std::thread thread;
  std::atomic<bool> listen_returned{false};
  int port = -1;
  int listening_socket = -1;  // the last socket httplib made (the one bound, once bind succeeds)
};

void HttpServer::Impl::handle(const httplib::Request& request, httplib::Response& response, std::string body) {
  http_detail::ConnectionGuard::request_answered();
  ApiRequest api_request = to_api_request(request, std::move(body));
  if (options.faults && origin_form_path(api_request.path).starts_with("/api/v1/")) {
    if (std::optional<ApiResponse> faulted = injected_fault(*options.faults, api_request)) {
      write_response(*faulted, response);
      return;
    }
  }
  write_response(handler.handle(api_request), response);
}

void HttpServer::Impl::handle_with_body(const httplib::Request& request, httplib::Response& response,
                                        const httplib::ContentReader& reader) {
  std::string body;
  bool too_large = false;
  const bool read = read_body(reader, options.max_body_bytes, body, too_large);
  // httplib sets 413 itself when Content-Length exceeds the limit (it skips that body).
  if (too_large || response.status == 413) {
    write_response(error_response(413, too_large_message(options.max_body_bytes)), response);
  } else if (!read) {
    write_response(error_response(400, "cannot read the request body"), response);
  } else {
    handle(request, response, std::move(body));
  }
}

void HttpServer::Impl::configure() {
  // Catch-all patterns: RequestHandler routes, so 404/405 and absolute-form paths are ours.
  const std::string any = ".*";
  auto plain = [this](const httplib::Request& rq, httplib::Response& rs) { handle(rq, rs, rq.body); };
  auto with_body = [this](const httplib::Request& rq, httplib::Response& rs, const httplib::ContentReader& reader) {
    handle_with_body(rq, rs, reader);
  };
  server.Get(any, plain).Delete(any, plain).Options(any, plain).Patch(any, plain);
  server.Post(any, with_body).Put(any, with_body);

  const std::size_t limit = options.max_body_bytes;
  server.set_error_handler(httplib::Server::HandlerWithResponse(
      [limit](const httplib::Request&, httplib::Response& response) { return fill_error_body(response, limit); }));
  server.set_exception_handler([](const httplib::Request&, httplib::Response& response, std::exception_ptr) {
    write_response(error_response(500, "internal error"), response);
  });
  server.set_logger([](const httplib::Request& request, const httplib::Response& response) {
    spdlog::debug("HTTP {} {} {} -> {}", request.remote_addr, request.method, request.target, response.status);
  });
  configure_connections();
}

void HttpServer::Impl::configure_connections() {
  // httplib's default sets SO_REUSEPORT, which lets a second daemon bind the same port and take
  // half of the connections; SO_REUSEADDR alone allows a quick restart and refuses a duplicate.
  server.set_socket_options([this](int sock) {
    const int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    listening_socket = sock;
  });
  // Headers and body go out in separate writes: without TCP_NODELAY the body waits for the
  // client's delayed ACK (40 ms per response on Linux).
  server.set_tcp_nodelay(true);
  server.set_payload_max_length(options.max_body_bytes);
  server.set_read_timeout(options.read_timeout);
  server.set_write_timeout(options.write_timeout);
  server.set_keep_alive_timeout(options.keep_alive_timeout.count());
  server.set_keep_alive_max_count(options.keep_alive_max_requests);
  const std::size_t threads = options.max_connections;
  server.new_task_queue = [threads] {
    return new http_detail::ConnectionThreads(threads, std::chrono::milliseconds(10'000));
  };
}

HttpServer::HttpServer(Sensor& sensor, HttpServerOptions options)
    : impl_(std::make_unique<Impl>(sensor, std::move(options))) {
  impl_->configure();
}

HttpServer::~HttpServer() { stop(); }

void HttpServer::start() {
  auto& impl = *impl_;
  if (impl.thread.joinable()) return;
  const auto& address = impl.options.address;
  const int requested = impl.options.port;
  impl.port = requested == 0 ? impl.server.bind_to_any_port(address)
                             : (impl.server.bind_to_port(address, requested) ? requested : -1);
  if (impl.port < 0) {
    const int error_number = bind_errno(address, requested);
    throw BindError(describe_bind_error(address, requested, error_number), error_number);
  }
  // httplib (Debian's 0.11) listens with a backlog of 5: a burst of connections overflowed it, and
  // every sixth connect of a loop waited a second for its SYN to be sent again. Linux takes a new
  // backlog when listen() is called again on a listening socket.
  ::listen(impl.listening_socket, SOMAXCONN);
  impl.thread = std::thread([&impl] {
    impl.server.listen_after_bind();
    impl.listen_returned = true;
  });
  // httplib's stop() does nothing until the accept loop runs (it checks is_running()): wait.
  while (!impl.server.is_running() && !impl.listen_returned) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  spdlog::info("HTTP API{} on http://{}:{}/api/v1/", log_tag(impl.options.name), address, impl.port);
}

void HttpServer::stop() {
  if (!impl_->thread.joinable()) return;
  impl_->server.stop();
  impl_->thread.join();
}

int HttpServer::port() const { return impl_->port; }

const std::string& HttpServer::address() const { return impl_->options.address; }

}  // namespace lidartwin
