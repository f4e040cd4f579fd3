// serve --ideal means what record --ideal means (cli/sensor_physics.h): a served scan of a fixed
// pose carries, pixel for pixel, the ranges `record --ideal` writes for the same scene and pose.
#include <chrono>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "support/record_capture.h"

namespace lidartwin::e2e::serve_ideal_test {
namespace {

// The ranges of every pixel of one frame of `record --ideal` of the room (512x10, os1-32).
Scan recorded_ideal_frame() {
  const auto dir = scratch_dir() / "ideal_record";
  std::filesystem::remove_all(dir);
  const std::string args = "record --profile os1-32 --scene '" + room_scene().string() + "' --pose '" + kRoomPose +
                           "' --mode 512x10 --frames 1 --threads 1 --ideal --out '" + dir.string() +
                           "' > /dev/null 2>&1";
  EXPECT_EQ(test::run_lidartwin(args), 0) << args;
  const test::DecodedCapture capture = test::decode_capture(dir);
  EXPECT_EQ(capture.frames.size(), 1u);
  return capture.frames.begin()->second;
}

// Counts the pixels whose range differs between a served scan and the recorded one.
size_t differing_ranges(const Scan& served, const Scan& recorded) {
  size_t differing = 0;
  for (int m = 0; m < served.width; ++m) {
    for (int beam = 0; beam < served.height; ++beam) {
      differing += served.at(ChannelField::kRange, m, beam) != recorded.at(ChannelField::kRange, m, beam);
    }
  }
  return differing;
}

Scan served_frame(bool ideal) {
  UdpSocket lidar;
  auto args = room_args();
  if (ideal) args.push_back("--ideal");
  Daemon daemon("127.0.0.1", 0, args);
  SensorHttp http(daemon.address(), daemon.http_port());
  ConfigRequest request;
  request.lidar_port = lidar.port();
  request.lidar_mode = "512x10";
  const Metadata metadata = parse(sdk016_init_client(http, request));
  ScanBatcher batcher(metadata.format);
  auto scans = receive_scans(lidar, batcher, 1, std::chrono::seconds(10));
  expect_complete_scans(scans, metadata, 1);
  return scans.empty() ? Scan() : scans.front().scan;
}

TEST(ServeIdeal, ServesExactlyTheRangesRecordIdealWrites) {
  const Scan recorded = recorded_ideal_frame();
  const Scan served = served_frame(true);
  ASSERT_EQ(served.width, recorded.width);
  ASSERT_EQ(served.height, recorded.height);
  EXPECT_EQ(differing_ranges(served, recorded), 0u);
}

// The comparison can tell: without --ideal the profile's noise moves most ranges off the ideal.
TEST(ServeIdeal, WithoutTheFlagTheRangesCarryNoise) {
  const Scan recorded = recorded_ideal_frame();
  const Scan served = served_frame(false);
  ASSERT_EQ(served.width, recorded.width);
  EXPECT_GT(differing_ranges(served, recorded), static_cast<size_t>(served.width * served.height / 2));
}

}  // namespace
}  // namespace lidartwin::e2e::serve_ideal_test
