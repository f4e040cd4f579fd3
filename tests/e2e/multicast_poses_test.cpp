// A rig spread over processes (issue 26): two `serve` daemons, each one sensor of the rig at its
// own address and mounting, join one multicast group for the vehicle's poses (--pose-udp
// 239.x.y.z:PORT) and stamp on one clock: the host's (across machines, hosts disciplined by PTP;
// here the daemons share one host's) or, in lock-step, the simulation's that the poses carry. One
// sender drives both. Their ground truth (serve --record's column_poses.tum) then shows that
// columns with equal timestamps observe the same vehicle pose.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "e2e/support/daemon.h"
#include "e2e/support/pose_sender.h"
#include "e2e/support/room.h"
#include "lidartwin/pose/pose.h"
#include "support/pose_inverse.h"

namespace lidartwin::e2e::multicast_poses_test {
namespace {

namespace fs = std::filesystem;

int64_t monotonic_ns() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return int64_t{now.tv_sec} * 1'000'000'000 + now.tv_nsec;
}

// The vehicle: 1 m/s along x while turning at 30 deg/s, 1.5 m up, in the room.
RigPose vehicle_at(int64_t t0_ns, int64_t time_ns, uint32_t sequence) {
  const double t = static_cast<double>(time_ns - t0_ns) * 1e-9;
  RigPose pose;
  pose.sequence = sequence;
  pose.time_ns = time_ns;
  pose.position = {-0.5 + 1.0 * t, 0.0, 1.5};
  pose.orientation = Eigen::AngleAxisd(0.5236 * t, Eigen::Vector3d::UnitZ());
  return pose;
}

// The clock the sender stamps its poses on, from the host's monotonic time: the host's own, or a
// simulation's that starts at 1 s and runs at twice real time (lock-step: the daemons have no other
// clock than the poses').
struct PoseStamps {
  bool simulation = false;
  int64_t host_start_ns = 0;
  int64_t at(int64_t host_ns) const { return simulation ? 1'000'000'000 + 2 * (host_ns - host_start_ns) : host_ns; }
};

// Sends to the group from the interface that has `from` (where the daemons joined it), at 200 Hz.
void send_poses(const std::string& from, const std::string& group, uint16_t port, const PoseStamps& stamps,
                int64_t t0_ns, std::chrono::milliseconds duration) {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  in_addr interface {};
  inet_pton(AF_INET, from.c_str(), &interface);
  setsockopt(fd, IPPROTO_IP, IP_MULTICAST_IF, &interface, sizeof interface);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  inet_pton(AF_INET, group.c_str(), &to.sin_addr);
  const auto end = std::chrono::steady_clock::now() + duration;
  for (uint32_t sequence = 0; std::chrono::steady_clock::now() < end; ++sequence) {
    const std::vector<uint8_t> bytes = pose_datagram(vehicle_at(t0_ns, stamps.at(monotonic_ns()), sequence));
    sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  close(fd);
}

constexpr const char* kMountA = "0.5 0.4 0.3 0 0 0.3826834 0.9238795";  // 45 deg left
constexpr const char* kMountB = "-0.5 -0.4 0.2 0 0 -0.3826834 0.9238795";

std::string pose_group_port() { return "239.255.77.77:" + std::to_string(20000 + getpid() % 30000); }

// A daemon of the rig; `lock_step`: on the simulation's clock instead of the host's.
std::vector<std::string> daemon_args(const std::string& listen, const char* mount, const fs::path& record,
                                     bool lock_step = false) {
  std::vector<std::string> args = {"--profile",    "os1-32",
                                   "--scene",      empty_room_scene().string(),
                                   "--threads",    "1",
                                   "--lidar-mode", "512x10",
                                   "--pose-udp",   listen,
                                   "--mount",      mount,
                                   "--record",     record.string()};
  if (lock_step) {
    args.emplace_back("--lock-step");
  } else {
    args.insert(args.end(), {"--pose-clock", "monotonic"});
  }
  return args;
}

// Sends the vehicle's motion to the group for 1.5 s from `from`'s interface, while daemons `a` and
// `b` (mountings kMountA, kMountB) record into dir/a and dir/b; then stops them and checks, from
// their ground truth (column_poses.tum), that columns with equal timestamps observe one vehicle pose,
// the one that was sent.
void expect_one_vehicle(Daemon& a, Daemon& b, const std::string& from, const fs::path& dir, bool lock_step = false) {
  const std::string listen = pose_group_port();
  const std::string group = listen.substr(0, listen.find(':'));
  const auto port = static_cast<uint16_t>(std::stoi(listen.substr(listen.find(':') + 1)));
  EXPECT_NE(a.log().find("multicast group joined on " + a.address()), std::string::npos) << a.log();
  EXPECT_NE(b.log().find("multicast group joined on " + b.address()), std::string::npos) << b.log();
  const PoseStamps stamps{lock_step, monotonic_ns()};
  const int64_t t0 = stamps.at(monotonic_ns());
  send_poses(from, group, port, stamps, t0, std::chrono::milliseconds(1500));
  const int64_t t1 = stamps.at(monotonic_ns());
  EXPECT_EQ(a.stop(), 0) << a.log();
  EXPECT_EQ(b.stop(), 0) << b.log();

  // The vehicle as each daemon placed it: each column's sensor pose less its mounting.
  const auto vehicle = [](const fs::path& file, const char* mount) {
    std::vector<StampedPose> poses = Trajectory::load_tum(file).samples();
    const Pose sensor_from_vehicle = test::inverse(parse_pose(mount));
    for (StampedPose& p : poses) p.pose = p.pose * sensor_from_vehicle;
    return poses;
  };
  const std::vector<StampedPose> from_a = vehicle(dir / "a" / "column_poses.tum", kMountA);
  const std::vector<StampedPose> from_b = vehicle(dir / "b" / "column_poses.tum", kMountB);
  // While poses arrived (not before the first nor past the last, where a daemon holds or
  // extrapolates), each of b's columns against a's pose at the same time, between a's two columns.
  const double begin_s = static_cast<double>(t0) * 1e-9 + 0.1, end_s = static_cast<double>(t1) * 1e-9 - 0.05;
  size_t compared = 0;
  double worst_m = 0.0, worst_rad = 0.0, worst_truth_m = 0.0;
  size_t k = 0;
  for (const StampedPose& pb : from_b) {
    if (pb.time_s < begin_s || pb.time_s > end_s) continue;
    while (k + 1 < from_a.size() && from_a[k + 1].time_s < pb.time_s) ++k;
    if (k + 1 >= from_a.size() || from_a[k].time_s > pb.time_s) continue;
    const StampedPose& p0 = from_a[k];
    const StampedPose& p1 = from_a[k + 1];
    if (p1.time_s - p0.time_s > 0.001) continue;  // a gap in a's columns (between frames)
    const double w = (pb.time_s - p0.time_s) / (p1.time_s - p0.time_s);
    const Eigen::Vector3d position = (1 - w) * p0.pose.translation + w * p1.pose.translation;
    const Eigen::Quaterniond rotation = p0.pose.rotation.slerp(w, p1.pose.rotation);
    worst_m = std::max(worst_m, (pb.pose.translation - position).norm());
    worst_rad = std::max(worst_rad, pb.pose.rotation.angularDistance(rotation));
    const RigPose truth = vehicle_at(t0, static_cast<int64_t>(pb.time_s * 1e9), 0);
    worst_truth_m = std::max(worst_truth_m, (pb.pose.translation - truth.position).norm());
    ++compared;
  }
  std::printf("compared %zu columns: vehicle pose apart by at most %.2e m, %.2e rad; %.2e m from the sent motion\n",
              compared, worst_m, worst_rad, worst_truth_m);
  EXPECT_GT(compared, lock_step ? 2000u : 1000u);  // lock-step: 3 s of the simulation
  EXPECT_LT(worst_m, 1e-4);
  EXPECT_LT(worst_rad, 1e-4);
  EXPECT_LT(worst_truth_m, 2e-3);  // both heard the sender: the pose it sent for that time
}

TEST(MulticastPoses, TwoDaemonsOfARigHearOneVehicleAndAgreeOnItsPoseAtEveryTimestamp) {
  const fs::path dir = scratch_dir() / "multicast_rig";
  fs::remove_all(dir);
  Daemon a("127.0.0.2", 0, daemon_args(pose_group_port(), kMountA, dir / "a"));
  Daemon b("127.0.0.3", 0, daemon_args(pose_group_port(), kMountB, dir / "b"));
  expect_one_vehicle(a, b, "127.0.0.1", dir);
}

// The same rig in lock-step: both daemons step on the simulation's time the multicast poses carry
// (here twice real time), stamp their columns with it, and still agree at every timestamp.
TEST(MulticastPoses, TwoLockStepDaemonsStepOnOneSimulationsClockAndAgreeOnTheVehiclesPose) {
  const fs::path dir = scratch_dir() / "multicast_lock_step_rig";
  fs::remove_all(dir);
  Daemon a("127.0.0.2", 0, daemon_args(pose_group_port(), kMountA, dir / "a", true));
  Daemon b("127.0.0.3", 0, daemon_args(pose_group_port(), kMountB, dir / "b", true));
  expect_one_vehicle(a, b, "127.0.0.1", dir, true);
}

// Two machines of a rig on one LAN, as two pods of a cluster: each daemon in a network namespace
// of its own, with one interface on a Linux bridge (veth pairs); the pose sender on the bridge
// itself, in this test's own namespace. Nothing but the bridge joins them.
class BridgedHosts {
 public:
  BridgedHosts() {
    if (unshare(CLONE_NEWNET) != 0) throw std::runtime_error("unshare(CLONE_NEWNET) failed");
    ip("link set lo up");
    // Snooping off: the bridge floods the group to every port, whatever IGMP it has seen.
    ip("link add lt-br type bridge mcast_snooping 0");
    ip("addr add 10.77.0.1/24 dev lt-br");
    ip("link set lt-br up");
    for (size_t k = 0; k < 2; ++k) {
      const std::string ns = namespaces_[k], port = "lt-port" + std::to_string(k), nic = "lt-nic" + std::to_string(k);
      ip("netns add " + ns);
      ip("link add " + nic + " type veth peer name " + port);
      ip("link set " + nic + " netns " + ns);
      ip("link set " + port + " master lt-br up");
      ip("-n " + ns + " link set lo up");
      ip("-n " + ns + " addr add " + address(k) + "/24 dev " + nic);
      ip("-n " + ns + " link set " + nic + " up");
    }
  }
  ~BridgedHosts() {
    for (const std::string& ns : namespaces_) std::system(("ip netns del " + ns + " 2>/dev/null").c_str());
  }
  BridgedHosts(const BridgedHosts&) = delete;
  BridgedHosts& operator=(const BridgedHosts&) = delete;

  const std::string& netns(size_t k) const { return namespaces_[k]; }
  static std::string address(size_t k) { return "10.77.0." + std::to_string(2 + k); }
  static std::string bridge_address() { return "10.77.0.1"; }

 private:
  static void ip(const std::string& args) {
    if (std::system(("ip " + args + " 2>&1").c_str()) != 0) throw std::runtime_error("ip " + args + " failed");
  }
  const std::string namespaces_[2] = {"lt-rig-a-" + std::to_string(getpid()), "lt-rig-b-" + std::to_string(getpid())};
};

TEST(MulticastPoses, TwoDaemonsInTwoNetworkNamespacesOnABridgeAgreeOnTheVehiclesPose) {
  if (!running_as_root()) GTEST_SKIP() << "network namespaces need root";
  const BridgedHosts hosts;
  const fs::path dir = scratch_dir() / "bridged_rig";
  fs::remove_all(dir);
  Daemon a(Daemon::Netns{hosts.netns(0)}, BridgedHosts::address(0), 0,
           daemon_args(pose_group_port(), kMountA, dir / "a"));
  Daemon b(Daemon::Netns{hosts.netns(1)}, BridgedHosts::address(1), 0,
           daemon_args(pose_group_port(), kMountB, dir / "b"));
  expect_one_vehicle(a, b, BridgedHosts::bridge_address(), dir);
}

// A group that cannot be joined (no interface has --address) is refused, naming the flag, the
// group and the interface.
TEST(MulticastPoses, AGroupThatCannotBeJoinedIsRefusedNamingIt) {
  const auto [code, output] = run_cli("serve --http-port 0 --address 10.254.254.254 --profile os1-32 --scene " +
                                      empty_room_scene().string() + " --pose-udp 239.255.77.78:0");
  EXPECT_EQ(code, 2) << output;
  EXPECT_NE(output.find("--pose-udp 239.255.77.78:0: cannot join the multicast group on 10.254.254.254"),
            std::string::npos)
      << output;
}

}  // namespace
}  // namespace lidartwin::e2e::multicast_poses_test
