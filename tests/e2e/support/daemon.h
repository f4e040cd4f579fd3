#pragma once
// Runs the real `lidartwin serve` binary (LIDARTWIN_BINARY) as a child process, the way a user
// would, and stops it with SIGTERM. The HTTP port is discovered from the daemon's log line, so
// tests can pass --http-port 0 and run in parallel without root. Header-only and free of gtest, so
// the streaming benchmark uses it too.
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include "e2e/support/log_port.h"

namespace lidartwin::e2e {

inline std::filesystem::path scratch_dir() {
  const auto dir = std::filesystem::temp_directory_path() / ("lidartwin-e2e-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

inline bool running_as_root() { return geteuid() == 0; }

class Daemon {
 public:
  // Starts `lidartwin serve --address address --http-port http_port args...` and waits until its
  // log says where HTTP answers. Throws with the daemon's log if it exits or times out first.
  Daemon(std::string address, int http_port, const std::vector<std::string>& args,
         std::chrono::seconds timeout = std::chrono::seconds(30))
      : address_(std::move(address)) {
    static std::atomic<int> counter{0};  // rig_bench starts daemons from several threads
    log_path_ = scratch_dir() / ("daemon-" + address_ + "-" + std::to_string(++counter) + ".log");
    std::vector<std::string> argv{LIDARTWIN_BINARY, "serve",       "--address",
                                  address_,         "--http-port", std::to_string(http_port)};
    argv.insert(argv.end(), args.begin(), args.end());
    spawn(argv);
    wait_until_ready(timeout);
  }
  // Starts `lidartwin serve args...` for a rig (--rig FILE among args) and waits until the sensor at
  // `address`, the rig's last, answers; port_of() gives each sensor's HTTP port.
  struct Rig {};
  Daemon(Rig, std::string address, const std::vector<std::string>& args,
         std::chrono::seconds timeout = std::chrono::seconds(30))
      : address_(std::move(address)), ready_prefix_("answering on http://" + address_) {
    static std::atomic<int> counter{0};
    log_path_ = scratch_dir() / ("rig-" + address_ + "-" + std::to_string(++counter) + ".log");
    std::vector<std::string> argv{LIDARTWIN_BINARY, "serve"};
    argv.insert(argv.end(), args.begin(), args.end());
    spawn(argv);
    wait_until_ready(timeout);
  }
  // Starts the daemon inside the named network namespace (`ip netns add NAME`; needs root), as on a
  // machine of its own.
  struct Netns {
    std::string name;
  };
  Daemon(Netns netns, std::string address, int http_port, const std::vector<std::string>& args,
         std::chrono::seconds timeout = std::chrono::seconds(30))
      : address_(std::move(address)), netns_("/var/run/netns/" + netns.name) {
    static int counter = 0;
    log_path_ = scratch_dir() / ("daemon-" + netns.name + "-" + address_ + "-" + std::to_string(++counter) + ".log");
    std::vector<std::string> argv{LIDARTWIN_BINARY, "serve",       "--address",
                                  address_,         "--http-port", std::to_string(http_port)};
    argv.insert(argv.end(), args.begin(), args.end());
    spawn(argv);
    wait_until_ready(timeout);
  }
  ~Daemon() {
    if (pid_ > 0) stop();
  }
  // The HTTP port of the sensor at `address` (a rig's), from the daemon's log; -1 if none answers there.
  int port_of(const std::string& address) const {
    return port_after(log(), "answering on http://" + address).value_or(-1);
  }
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  // SIGTERM, then the exit code (128 + signal if it died of one; -1 if it had to be killed).
  int stop(std::chrono::seconds timeout = std::chrono::seconds(15)) {
    if (pid_ <= 0) return exit_code_;
    kill(pid_, SIGTERM);
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    int status = 0;
    while (waitpid(pid_, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        kill(pid_, SIGKILL);
        waitpid(pid_, &status, 0);
        pid_ = -1;
        return exit_code_ = -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    pid_ = -1;
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    return exit_code_;
  }

  const std::string& address() const { return address_; }
  int http_port() const { return http_port_; }
  pid_t pid() const { return pid_; }
  std::string log() const {
    std::ifstream in(log_path_);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

 private:
  void spawn(const std::vector<std::string>& argv) {
    // Emptied here, before the child exists: the scratch directory is named by the test's pid, pids
    // wrap at 32768 on the CI machines, and a log left by an earlier run's test of the same pid
    // would otherwise be read before the child truncates it, its stale "answering on" line giving a
    // port nobody listens on (the occasional "GET ...: transport error (Connection)" at start-up).
    std::ofstream(log_path_, std::ios::trunc).close();
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      const int fd = open(log_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      if (!netns_.empty()) {
        const int ns = open(netns_.c_str(), O_RDONLY | O_CLOEXEC);
        if (ns < 0 || setns(ns, CLONE_NEWNET) != 0) {
          perror(("setns " + netns_).c_str());
          _exit(126);
        }
      }
      std::vector<char*> raw;
      for (const auto& arg : argv) raw.push_back(const_cast<char*>(arg.c_str()));
      raw.push_back(nullptr);
      execv(raw[0], raw.data());
      _exit(127);
    }
  }

  void wait_until_ready(std::chrono::seconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      if (const std::optional<int> port = port_after(log(), ready_prefix_)) {
        http_port_ = *port;
        return;
      }
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        throw std::runtime_error("lidartwin serve exited with " + std::to_string(exit_code_) + ":\n" + log());
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    throw std::runtime_error("lidartwin serve did not start in time:\n" + log());
  }

  std::string address_;
  std::string ready_prefix_ = "answering on http://";
  std::filesystem::path log_path_;
  std::string netns_;  // a network namespace's file; empty: the test's own
  pid_t pid_ = -1;
  int http_port_ = 0;
  int exit_code_ = 0;
};

// Runs `lidartwin args...` to completion: exit code and combined output.
inline std::pair<int, std::string> run_cli(const std::string& args) {
  const std::string command = std::string(LIDARTWIN_BINARY) + " " + args + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) throw std::runtime_error("popen failed");
  std::string output;
  char buffer[512];
  while (fgets(buffer, sizeof buffer, pipe)) output += buffer;
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

}  // namespace lidartwin::e2e
