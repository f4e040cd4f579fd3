// The image as users run it (issue 26), with podman: a container on a bridge network, healthy and
// streaming to an unmodified client; docker/compose.yaml brought up by docker-compose through
// podman's Docker API, and the Kubernetes manifests of docker/kubernetes/ played with
// `podman kube play`, every sensor reached. ctest label "container": tools/container-check builds
// the image (localhost/lidartwin:latest, around this build's binary) and runs these; the default
// test run leaves them out. Needs root and podman (tools/container-setup).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "e2e/support/room.h"  // Eigen before httplib

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/pose_sender.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"

namespace lidartwin::e2e {
namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;
const std::string kImage = "localhost/lidartwin:latest";
const std::string kPodman = "podman --runtime runc ";

// Runs a shell command: its exit code and output (stdout and stderr).
std::pair<int, std::string> sh(const std::string& command) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) throw std::runtime_error("popen failed: " + command);
  std::string output;
  char buffer[512];
  while (fgets(buffer, sizeof buffer, pipe)) output += buffer;
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

std::string trimmed(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text;
}

// Seconds until the sensor at `address` answers GET sensor_info, or -1 after `timeout`.
double seconds_until_answering(const std::string& address, std::chrono::steady_clock::time_point since,
                               std::chrono::seconds timeout = std::chrono::seconds(30)) {
  httplib::Client client(address, 80);
  client.set_connection_timeout(std::chrono::milliseconds(200));
  while (std::chrono::steady_clock::now() - since < timeout) {
    if (const auto answer = client.Get("/api/v1/sensor/metadata/sensor_info"); answer && answer->status == 200) {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return -1.0;
}

// A client as the SDK 1.0 is one: configures the sensor at `address`, then takes 3 scans of its
// packets, which must come from that address and be complete.
// A sensor goes on streaming to the ports its client configured after the client is done, as a
// real one does. Each client's ports therefore stay bound in `held` until the test ends: a port
// freed and handed by the kernel to the next sensor's client would receive both streams.
using HeldPorts = std::vector<std::unique_ptr<UdpSocket>>;

void expect_complete_scans_from(const std::string& address, HeldPorts& held, const std::string& mode = "512x10") {
  SCOPED_TRACE("sensor " + address);
  UdpSocket& lidar = *held.emplace_back(std::make_unique<UdpSocket>());
  UdpSocket& imu = *held.emplace_back(std::make_unique<UdpSocket>());
  SensorHttp http(address, 80);
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.imu_port = imu.port();
  request.lidar_mode = mode;
  const Metadata metadata = parse(sdk10_sensor_packet_source(http, request));
  ScanBatcher batcher(metadata.format);
  expect_complete_scans(receive_scans(lidar, batcher, 3, std::chrono::seconds(20), address), metadata, 3);
}

class Container : public ::testing::Test {
 protected:
  void SetUp() override {
    if (geteuid() != 0) GTEST_SKIP() << "podman here needs root";
    const auto [code, output] = sh(kPodman + "image exists " + kImage);
    ASSERT_EQ(code, 0) << kImage << " is not built: run tools/container-check\n" << output;
  }
};

// The image's own command (serve --address 0.0.0.0) on podman's bridge network: the health check
// passes and a client on the host gets complete scans from the container's address.
TEST_F(Container, TheImageIsHealthyAndStreamsCompleteScansToAClientOnTheHost) {
  const std::string name = "lidartwin-check-" + std::to_string(getpid());
  const auto started = std::chrono::steady_clock::now();
  const auto [code, output] = sh(kPodman + "run -d --rm --name " + name + " " + kImage);
  ASSERT_EQ(code, 0) << output;
  struct Stop {
    std::string name;
    ~Stop() { sh(kPodman + "stop -t 2 " + name); }
  } stop{name};
  const std::string address = trimmed(sh(kPodman + "inspect -f '{{.NetworkSettings.IPAddress}}' " + name).second);
  ASSERT_FALSE(address.empty());
  const double answering_s = seconds_until_answering(address, started);
  ASSERT_GT(answering_s, 0.0) << sh(kPodman + "logs " + name).second;
  const std::string size = trimmed(sh(kPodman + "image inspect -f '{{.Size}}' " + kImage).second);
  std::printf("image %s: %.1f MB; from podman run to the HTTP API answering: %.2f s\n", kImage.c_str(),
              std::stod(size) / 1e6, answering_s);

  EXPECT_EQ(sh(kPodman + "healthcheck run " + name).first, 0) << "the image's HEALTHCHECK";
  EXPECT_EQ(trimmed(sh(kPodman + "exec " + name + " id -u").second), "10001") << "the sensor runs without root";
  HeldPorts held;
  expect_complete_scans_from(address, held);
}

// docker-compose (Debian's 1.29) driving podman through its Docker-compatible API, on a socket of
// its own for the scope: docker/compose.yaml as a Docker user runs it. (podman-compose 1.0.3 cannot
// read a service's network given as a map with ipv4_address.)
class Compose {
 public:
  Compose()
      : socket_("/tmp/lidartwin-compose-" + std::to_string(getpid()) + ".sock"),
        compose_("DOCKER_HOST=unix://" + socket_ + " docker-compose -f " + kSource +
                 "/docker/compose.yaml -p lidartwin-compose-check ") {
    service_ = fork();
    if (service_ == 0) {
      execlp("podman", "podman", "--runtime", "runc", "system", "service", "--time=0", ("unix://" + socket_).c_str(),
             static_cast<char*>(nullptr));
      _exit(127);
    }
    for (int i = 0; i < 100 && access(socket_.c_str(), F_OK) != 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    sh(compose_ + "--profile one-process down -t 2");  // a run interrupted earlier
  }
  ~Compose() {
    sh(compose_ + "--profile one-process down -t 2");
    if (service_ > 0) {
      kill(service_, SIGTERM);
      waitpid(service_, nullptr, 0);
    }
    unlink(socket_.c_str());
  }
  Compose(const Compose&) = delete;
  Compose& operator=(const Compose&) = delete;

  // `docker-compose <arguments>`: its exit code and output.
  std::pair<int, std::string> operator()(const std::string& arguments) const { return sh(compose_ + arguments); }

 private:
  std::string socket_;
  std::string compose_;
  pid_t service_ = -1;
};

// Plays a manifest of docker/kubernetes/ and takes it down again at the end of the scope.
class KubePlay {
 public:
  explicit KubePlay(const std::string& manifest) : manifest_(kSource + "/docker/kubernetes/" + manifest) {
    sh(kPodman + "kube down " + manifest_);  // a run interrupted earlier
    const auto [code, output] = sh(kPodman + "kube play " + manifest_);
    if (code != 0) throw std::runtime_error("podman kube play " + manifest_ + ":\n" + output);
  }
  ~KubePlay() { sh(kPodman + "kube down " + manifest_); }
  KubePlay(const KubePlay&) = delete;
  KubePlay& operator=(const KubePlay&) = delete;

 private:
  std::string manifest_;
};

// Sends the vehicle standing still in the plant to the rig's multicast group on the loopback, at
// 100 Hz, stamped on CLOCK_MONOTONIC, until stopped.
class VehiclePoses {
 public:
  VehiclePoses() : thread_([this](const std::stop_token& stop) { send(stop); }) {}

 private:
  static void send(const std::stop_token& stop) {
    const int fd = socket(AF_INET, SOCK_DGRAM, 0);
    in_addr loopback{};
    inet_pton(AF_INET, "127.0.0.1", &loopback);
    setsockopt(fd, IPPROTO_IP, IP_MULTICAST_IF, &loopback, sizeof loopback);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(7600);
    inet_pton(AF_INET, "239.255.77.1", &to.sin_addr);
    for (uint32_t sequence = 0; !stop.stop_requested(); ++sequence) {
      RigPose pose;
      pose.sequence = sequence;
      pose.time_ns = monotonic_now_ns();
      pose.position = {12.0, 9.0, 0.0};  // on the plant's ground, by its first trajectory pose
      const std::vector<uint8_t> bytes = pose_datagram(pose);
      sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    close(fd);
  }
  std::jthread thread_;
};

struct Expected {
  std::string address;
  std::string prod_line;
};

void expect_each_its_own_sensor(const std::vector<Expected>& sensors) {
  std::set<std::string> serials;
  for (const Expected& sensor : sensors) {
    ASSERT_GT(seconds_until_answering(sensor.address, std::chrono::steady_clock::now()), 0.0) << sensor.address;
    SensorHttp http(sensor.address, 80);
    const json info = http.get_json("sensor/metadata/sensor_info");
    EXPECT_EQ(info.at("prod_line"), sensor.prod_line) << sensor.address;
    serials.insert(info.at("prod_sn").get<std::string>());
  }
  EXPECT_EQ(serials.size(), sensors.size()) << "each sensor has its own serial number";
}

// docker/compose.yaml: three sensors, each its own container at the address the file gives it on
// the rig's network; then the same vehicle as one `serve --rig` process (profile one-process).
TEST_F(Container, TheComposeRigsSensorsEachAnswerAtTheirOwnAddressAndStream) {
  if (sh("command -v docker-compose").first != 0) GTEST_SKIP() << "docker-compose: tools/container-setup installs it";
  const Compose compose;
  const auto [code, output] = compose("up -d --no-build");
  ASSERT_EQ(code, 0) << output;
  const std::vector<Expected> sensors{
      {"172.28.0.11", "OS-1-64"}, {"172.28.0.12", "OS-0-32-U1"}, {"172.28.0.13", "OS-2-128"}};
  expect_each_its_own_sensor(sensors);
  HeldPorts held;
  for (const Expected& sensor : sensors) expect_complete_scans_from(sensor.address, held);
  if (HasFailure()) std::printf("%s\n", compose("logs").second.c_str());
  ASSERT_EQ(compose("down -t 2").first, 0);

  const auto [one_code, one_output] = compose("--profile one-process up -d --no-build vehicle");
  ASSERT_EQ(one_code, 0) << one_output;
  const std::vector<Expected> rig{{"127.0.0.2", "OS-1-128"}, {"127.0.0.3", "OS-0-32-U1"}, {"127.0.0.4", "OS-0-32-U1"}};
  expect_each_its_own_sensor(rig);
  for (const Expected& sensor : rig) expect_complete_scans_from(sensor.address, held);
  if (HasFailure()) std::printf("%s\n", compose("--profile one-process logs").second.c_str());
}

// docker/kubernetes/rig-pod.yaml: one container per sensor, all following one multicast pose stream.
TEST_F(Container, TheKubernetesPodsSensorsEachStreamFollowingOneMulticastPoseStream) {
  const KubePlay pod("rig-pod.yaml");
  const VehiclePoses poses;
  const std::vector<Expected> sensors{
      {"127.0.0.12", "OS-1-128"}, {"127.0.0.13", "OS-0-32-U1"}, {"127.0.0.14", "OS-0-32-U1"}};
  expect_each_its_own_sensor(sensors);
  // Three processes loading the plant at once, casting niced (no CAP_SYS_NICE in a container) and
  // a live pose's few milliseconds ahead: their first second has late packets (logged). Clients
  // come once it has passed.
  std::this_thread::sleep_for(std::chrono::seconds(2));
  HeldPorts held;
  for (const Expected& sensor : sensors) expect_complete_scans_from(sensor.address, held);
  if (HasFailure()) {
    for (const char* container : {"roof", "left", "right"}) {
      std::printf("%s\n", sh(kPodman + "logs lidartwin-rig-" + container).second.c_str());
    }
  }
}

// docker/kubernetes/rig-deployment.yaml: serve --rig rigs/vehicle.json, one process.
TEST_F(Container, TheKubernetesDeploymentServesTheExampleRigFromOneProcess) {
  const KubePlay deployment("rig-deployment.yaml");
  const std::vector<Expected> sensors{
      {"127.0.0.2", "OS-1-128"}, {"127.0.0.3", "OS-0-32-U1"}, {"127.0.0.4", "OS-0-32-U1"}};
  expect_each_its_own_sensor(sensors);
  HeldPorts held;
  for (const Expected& sensor : sensors) expect_complete_scans_from(sensor.address, held);
}

}  // namespace
}  // namespace lidartwin::e2e
