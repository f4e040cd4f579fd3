// Bind failures explained (protocol doc 2.1: port 80 on localhost needs privileges).
#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <memory>
#include <system_error>

#include "http_api/bind_probe.h"
#include "lidartwin/http_api/http_server.h"

namespace lidartwin {
namespace {

std::string binary_path() {
  std::error_code error;
  const auto path = std::filesystem::read_symlink("/proc/self/exe", error);
  return error ? "<lidartwin binary>" : path.string();
}

std::string privileged_port_help(int port) {
  return " Ports below 1024 need privileges; any one of these works: run lidartwin as root; "
         "`sudo setcap cap_net_bind_service=+ep " +
         binary_path() + "`; `sudo sysctl net.ipv4.ip_unprivileged_port_start=" + std::to_string(port) +
         "`; or serve on a high port with `--http-port 8080` and point the clients at it with "
         "`http_proxy=http://127.0.0.1:8080` (libcurl and python-requests honour it; "
         "protocol doc 2.1).";
}

}  // namespace

int bind_errno(const std::string& address, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  if (::getaddrinfo(address.c_str(), service.c_str(), &hints, &found) != 0 || !found) {
    return EADDRNOTAVAIL;
  }
  const std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> owner(found, &::freeaddrinfo);
  const int sock = ::socket(found->ai_family, found->ai_socktype, found->ai_protocol);
  if (sock < 0) return errno;
  const int yes = 1;
  ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  const int result = ::bind(sock, found->ai_addr, found->ai_addrlen) == 0 ? 0 : errno;
  ::close(sock);
  return result;
}

std::string describe_bind_error(const std::string& address, int port, int error_number) {
  const std::string where = "cannot serve HTTP on " + address + ":" + std::to_string(port) + ": ";
  switch (error_number) {
    case EACCES:
    case EPERM: return where + "permission denied." + (port < 1024 ? privileged_port_help(port) : "");
    case EADDRINUSE:
      return where +
             "the address is in use (another lidartwin or web server?). Stop it, or give "
             "this sensor its own address (127.0.0.2, ...) or another --http-port.";
    case EADDRNOTAVAIL:
      return where +
             "no such local address. Use an address of this host; on Linux every "
             "127.x.y.z is local, so each virtual sensor can have its own.";
    default: return where + (error_number ? std::strerror(error_number) : "bind failed") + ".";
  }
}

}  // namespace lidartwin
