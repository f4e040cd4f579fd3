// Bad HTTP requests while streaming (DESIGN.md: the daemon never dies on bad input and never
// half-applies a config): each gets a 4xx, the lidar stream goes on without a gap longer than a
// few packet periods, and the config and init_id stay as they were.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e::bad_requests_test {
namespace {

// Kernel arrival times of every lidar datagram (the daemon's send times, whatever the test
// thread's scheduling), read on a thread of its own.
class ArrivalRecorder {
 public:
  explicit ArrivalRecorder(UdpSocket& socket)
      : thread_([this, &socket] {
          while (!stop_) {
            if (auto d = socket.receive(std::chrono::milliseconds(50))) arrivals_.push_back(d->arrived_ns);
          }
        }) {}
  std::vector<int64_t> finish() {
    stop_ = true;
    thread_.join();
    return arrivals_;
  }

 private:
  std::atomic<bool> stop_{false};
  std::vector<int64_t> arrivals_;
  std::thread thread_;
};

void send_raw_garbage(const std::string& address, int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<uint16_t>(port));
  inet_pton(AF_INET, address.c_str(), &to.sin_addr);
  if (connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to) == 0) {
    const std::string garbage = "\x16\x03\x01 NOT HTTP AT ALL\r\n\r\n";
    [[maybe_unused]] const auto sent = write(fd, garbage.data(), garbage.size());
  }
  close(fd);
}

TEST(BadRequests, StreamGoesOnAndConfigIsUnchanged) {
  UdpSocket lidar;
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  ScanBatcher warmup(metadata.format);
  expect_complete_scans(receive_scans(lidar, warmup, 1, std::chrono::seconds(10)), metadata, 1);
  const json config_before = http.get_json("sensor/config");

  ArrivalRecorder recorder(lidar);
  const std::string config = "/api/v1/sensor/config?staging=true&reinit=true&persist=false";
  const std::vector<std::pair<std::string, std::string>> bad_posts{
      {config, "{not json"},
      {config, R"({"lidar_mode": "999x10"})"},
      {config, R"({"udp_port_lidar": "abc"})"},
      {config, R"({"azimuth_window": [0]})"},
      {config, R"({"lidar_mode": "2048x10", "udp_profile_lidar": "NO_SUCH_PROFILE"})"},
      {config, "[1, 2, 3]"},
      {"/api/v1/sensor/config?staging=true&reinit=true", std::string(2 << 20, 'x')},
  };
  for (const auto& [path, body] : bad_posts) {
    const auto result = http.raw_post(path, body);
    if (!result && body.size() > (1u << 20)) continue;  // refused mid-upload: also a refusal
    ASSERT_TRUE(result) << path;
    EXPECT_GE(result->status, 400) << body.substr(0, 60);
    EXPECT_LT(result->status, 500) << body.substr(0, 60);
  }
  for (const std::string path : {"/api/v1/no/such/endpoint", "/api/v1/sensor/cmd/get_config_param?args=nonsense",
                                 "/api/v1/sensor/metadata/no_such_section"}) {
    const auto result = http.raw_get(path);
    ASSERT_TRUE(result) << path;
    EXPECT_GE(result->status, 400) << path;
    EXPECT_LT(result->status, 500) << path;
  }
  send_raw_garbage(daemon.address(), daemon.http_port());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto arrivals = recorder.finish();

  // 512x10: a packet every 3.125 ms (6.1); allow 5 periods for a loaded CI machine.
  ASSERT_GT(arrivals.size(), 50u);
  int64_t worst_gap = 0;
  for (size_t i = 1; i < arrivals.size(); ++i) worst_gap = std::max(worst_gap, arrivals[i] - arrivals[i - 1]);
  EXPECT_LT(worst_gap, 5 * 3'125'000) << "largest gap between lidar packets, ns";

  EXPECT_EQ(http.get_json("sensor/config"), config_before);
  EXPECT_EQ(http.get_json("sensor/metadata/sensor_info").at("initialization_id"),
            metadata.sensor_info.initialization_id);
  lidar.drain();
  ScanBatcher after(metadata.format);
  expect_complete_scans(receive_scans(lidar, after, 2, std::chrono::seconds(10)), metadata, 2);
  EXPECT_EQ(daemon.stop(), 0) << daemon.log();
}

}  // namespace
}  // namespace lidartwin::e2e::bad_requests_test
