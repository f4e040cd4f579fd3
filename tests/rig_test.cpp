// Several VirtualSensors in one process, as a rig holds them: one scene, one motion, one io_context
// and one worker pool. Each answers on its own address and sends its own packets, and an SDK-1.0
// client of each gets complete scans carrying its sensor's serial number.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

// Eigen (through lidartwin's headers) before httplib (through sdk_client.h): <resolv.h>, which
// httplib includes, defines a macro `res` that breaks Eigen's product kernels.
#include "lidartwin/pose/live_poses.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/rig/virtual_sensor.h"
#include "support/test_scene.h"
// clang-format off
#include "e2e/support/batcher.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
// clang-format on

namespace lidartwin {
namespace {

using e2e::UdpSocket;

VirtualSensorSetup setup_for(const std::string& address, const std::string& serial) {
  const SensorProfile profile = load_profile("os1-32");
  VirtualSensorSetup setup;
  setup.identity.prod_line = profile.prod_line;
  setup.identity.prod_pn = profile.prod_pn;
  setup.identity.prod_sn = serial;
  setup.identity.beams = profile.beams;
  setup.identity.limits.lidar_modes = profile.lidar_modes;
  setup.http.address = address;
  setup.http.port = 0;
  setup.streamer.source_address = asio::ip::make_address_v4(address).to_bytes();
  setup.max_range_m = profile.max_range_m;
  setup.chain = EffectChain::from_json(profile.effects, "os1-32");
  setup.seed = 7;
  return setup;
}

// ctest runs this file's tests side by side, each in a process of its own: each writes its own
// room (a shared path was rewritten and removed under another's Scene::load: "not a readable glTF").
Scene room_scene() {
  const auto dir = std::filesystem::temp_directory_path() / ("lidartwin_rig_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  test::write_glb(dir / "room.glb", {test::box("room", {-4, -3, -1.5}, {4, 3, 1.5}, 0.4f)});
  Scene scene = Scene::load(dir / "room.glb");
  std::filesystem::remove_all(dir);
  return scene;
}

TEST(Rig, SensorsShareOneScenePoolAndIoContextAndKeepTheirOwnIdentity) {
  const Scene scene = room_scene();
  const StaticPose poses(Pose{});
  asio::io_context io;
  WorkerPool pool(2);
  // One time base, as a rig's sensors share one (sensor/time_base.h).
  const RigContext rig{io, scene,   poses,   pool,
                       0,  nullptr, nullptr, std::make_shared<const TimeBase>(TimeBase::from_host())};
  std::vector<std::unique_ptr<VirtualSensor>> sensors;
  sensors.push_back(std::make_unique<VirtualSensor>(rig, setup_for("127.0.0.1", "122201000001")));
  sensors.push_back(std::make_unique<VirtualSensor>(rig, setup_for("127.0.0.2", "122201000002")));
  for (auto& sensor : sensors) sensor->start();
  auto guard = asio::make_work_guard(io);
  std::thread io_thread([&io] { io.run(); });

  for (auto& sensor : sensors) {
    UdpSocket lidar;
    UdpSocket imu;
    e2e::SensorHttp http(sensor->http().address(), sensor->http().port());
    e2e::ConfigRequest request;
    request.lidar_port = lidar.port();
    request.imu_port = imu.port();
    request.lidar_mode = "512x10";
    const Metadata metadata = e2e::parse(e2e::sdk10_sensor_packet_source(http, request));
    EXPECT_EQ(metadata.sensor_info.prod_sn, sensor->sensor().identity().prod_sn);
    ScanBatcher batcher(metadata.format);
    e2e::expect_complete_scans(
        e2e::receive_scans(lidar, batcher, 2, std::chrono::seconds(15), sensor->http().address()), metadata, 2);
    const auto datagram = imu.receive(std::chrono::seconds(2));
    ASSERT_TRUE(datagram);
    EXPECT_EQ(datagram->source_ip, sensor->http().address());
  }

  // Each sensor reports its own stream's health (issue 26: when the host cannot keep up, per
  // sensor, never a silent slowdown): its telemetry counts its own packets, stalls, skips and
  // send lateness. Stats reach the telemetry once a second.
  for (auto& sensor : sensors) {
    e2e::SensorHttp http(sensor->http().address(), sensor->http().port());
    e2e::json stats;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    do {
      stats = http.get_json("sensor/telemetry").at("lidartwin");
      if (stats.at("frames_sent").get<uint64_t>() > 0) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    } while (std::chrono::steady_clock::now() < deadline);
    EXPECT_GT(stats.at("lidar_packets_sent").get<uint64_t>(), 0u) << stats;
    for (const char* key : {"render_stalls", "late_packets", "skipped_packets", "send_lateness_p50_us",
                            "send_lateness_p99_us", "max_lateness_us", "render_load"}) {
      EXPECT_TRUE(stats.contains(key)) << key << " in " << stats;
    }
    EXPECT_LE(stats.at("send_lateness_p50_us").get<double>(), stats.at("send_lateness_p99_us").get<double>());
  }

  // The rig stops as serve does: streaming on the io thread, then everything else.
  asio::post(io, [&] {
    for (auto& sensor : sensors) sensor->stop_streaming();
  });
  guard.reset();
  io_thread.join();
  for (auto& sensor : sensors) sensor->stop();
}

// Live poses while the sensor streams (under ThreadSanitizer in tools/test): a pose arriving after
// a packet was cast has it cast again into the packet's second buffer, on the render worker, while
// the send clock reads whichever copy was published (render_ahead.h). Every packet of every frame
// arrives and packets are cast again. (Not every column need be valid: under TSan's slowdown, beside
// other tests, some packets miss their deadline and go out blank, as on a host short of CPU.)
TEST(Rig, LivePosesCastPacketsAgainWhileTheSendClockReadsThem) {
  const Scene scene = room_scene();
  LivePoseOptions options;
  options.clock = PoseClock::kMonotonic;
  const int64_t epoch = host_steady_ns();
  LivePoses live(options, epoch);
  asio::io_context io;
  WorkerPool pool(2);
  const RigContext rig{io,    scene, live,    pool,
                       epoch, &live, nullptr, std::make_shared<const TimeBase>(TimeBase::from_host())};
  VirtualSensorSetup setup = setup_for("127.0.0.1", "122201000003");
  setup.streamer.cast_ahead_ms = 20;  // every packet waits long enough for a pose or two
  VirtualSensor sensor(rig, setup);
  sensor.start();
  auto guard = asio::make_work_guard(io);
  std::thread io_thread([&io] { io.run(); });
  std::atomic<bool> flying{true};
  std::thread vehicle([&] {  // a slow turn, a pose every 5 ms
    for (uint32_t sequence = 1; flying; ++sequence) {
      PoseMessage message;
      message.sequence = sequence;
      message.time_ns = host_steady_ns();
      const double t = static_cast<double>(message.time_ns - epoch) * 1e-9;
      message.pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * t, Eigen::Vector3d::UnitZ()));
      live.receive(message, host_steady_ns());
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });

  UdpSocket lidar;
  e2e::SensorHttp http(sensor.http().address(), sensor.http().port());
  e2e::ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = e2e::parse(e2e::sdk10_sensor_packet_source(http, request));
  ScanBatcher batcher(metadata.format);
  const std::vector<BatchedFrame> scans = e2e::receive_scans(lidar, batcher, 4, std::chrono::seconds(15));
  ASSERT_EQ(scans.size(), 4u);
  for (size_t i = 0; i < scans.size(); ++i) {
    EXPECT_TRUE(scans[i].complete) << "frame " << scans[i].frame_id << ": " << scans[i].packets << " packets";
    if (i > 0) {
      EXPECT_EQ(scans[i].frame_id, scans[i - 1].frame_id + 1);
    }
  }
  uint64_t recast = 0;
  e2e::json status;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (recast == 0 && std::chrono::steady_clock::now() < deadline) {  // stats reach it once a second
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const auto response = http.raw_get("/lidartwin/v1/pose");
    if (!response || response->status != 200) continue;  // a slow answer under TSan: ask again
    status = e2e::json::parse(response->body);
    recast = status.at("recast_packets").get<uint64_t>();
  }
  EXPECT_GT(recast, 0u) << status.dump(2);

  flying = false;
  vehicle.join();
  asio::post(io, [&] { sensor.stop_streaming(); });
  guard.reset();
  io_thread.join();
  sensor.stop();
}

}  // namespace
}  // namespace lidartwin
