// ScanBatcher on real windowed captures (protocol doc 6.4, 6.5): which packets make a frame, when
// it is released, and which packets the SDK would drop.
#include <filesystem>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/packet/scan_batcher.h"
#include "lidartwin/pcap/pcap.h"

namespace lidartwin {
namespace {

const std::filesystem::path kSamples = std::filesystem::path(LIDARTWIN_TEST_DATA) / "ouster-samples";

struct Capture {
  Metadata metadata;
  std::vector<std::vector<uint8_t>> lidar;  // payloads of the lidar packet size, in capture order
};

Capture load(const std::string& pcap, const std::string& json) {
  Capture capture{load_metadata(kSamples / json), {}};
  const size_t size = PacketFormat(capture.metadata.format).lidar_packet_size();
  for (const UdpDatagram& d : read_pcap(kSamples / pcap)) {
    if (d.payload.size() == size) capture.lidar.push_back(d.payload);
  }
  return capture;
}

int valid_columns(const Scan& scan) {
  int valid = 0;
  for (const uint32_t status : scan.status) valid += (status & 1u) ? 1 : 0;
  return valid;
}

// STANDARD header (4.3): frame_id at bytes 2-3, init_id at 4-6. These FW 2.3 packets carry no CRC.
std::vector<uint8_t> with_frame_id(std::vector<uint8_t> packet, uint16_t frame_id) {
  packet[2] = static_cast<uint8_t>(frame_id & 0xFF);
  packet[3] = static_cast<uint8_t>(frame_id >> 8);
  return packet;
}
std::vector<uint8_t> with_init_id(std::vector<uint8_t> packet, uint32_t init_id) {
  for (int i = 0; i < 3; ++i) packet[static_cast<size_t>(4 + i)] = static_cast<uint8_t>(init_id >> (8 * i));
  return packet;
}

// windowed_frame1: azimuth window [180000, 360000] -> columns [1, 256] at 512: 17 packets.
TEST(ScanBatcher, WindowedFrameIsReleasedWhenItsLastPacketArrives) {
  const Capture c = load("windowed_frame1.pcap", "windowed_frame1_0.json");
  ASSERT_EQ(c.lidar.size(), 17u);
  ScanBatcher batcher(c.metadata.format);
  EXPECT_EQ(batcher.expected_packets(), 17u);
  std::vector<BatchedFrame> frames;
  for (const auto& packet : c.lidar) {
    if (auto frame = batcher.add(packet)) frames.push_back(std::move(*frame));
  }
  ASSERT_EQ(frames.size(), 1u);  // without waiting for the next frame or a flush
  EXPECT_TRUE(frames[0].complete);
  EXPECT_EQ(frames[0].packets, 17u);
  EXPECT_EQ(valid_columns(frames[0].scan), 256);
  EXPECT_EQ(frames[0].scan.status[0] & 1u, 0u);  // m = 0 is sent, but outside the window
  EXPECT_EQ(frames[0].scan.status[256] & 1u, 1u);
  EXPECT_EQ(frames[0].init_ids, std::set<uint32_t>{c.metadata.sensor_info.initialization_id});
  EXPECT_FALSE(batcher.flush().has_value());
}

// windowed_frame2: [370, 85] wraps through 0; both parts are one frame (6.2).
TEST(ScanBatcher, WrappingWindowIsOneFrame) {
  const Capture c = load("windowed_frame2.pcap", "windowed_frame2_0.json");
  ScanBatcher batcher(c.metadata.format);
  EXPECT_EQ(batcher.expected_packets(), 15u);
  std::optional<BatchedFrame> frame;
  for (const auto& packet : c.lidar) {
    if (auto released = batcher.add(packet)) frame = std::move(released);
  }
  ASSERT_TRUE(frame.has_value());
  EXPECT_TRUE(frame->complete);
  EXPECT_EQ(valid_columns(frame->scan), (511 - 370 + 1) + (85 + 1));
  EXPECT_EQ(frame->scan.packet_received[100 / 16], 0u);  // 96-367 are not sent
}

TEST(ScanBatcher, ANewFrameReleasesTheOpenOneAsItIs) {
  const Capture c = load("windowed_frame1.pcap", "windowed_frame1_0.json");
  ScanBatcher batcher(c.metadata.format);
  for (size_t i = 0; i < 5; ++i) EXPECT_FALSE(batcher.add(c.lidar[i]).has_value());
  const uint32_t frame_id = batcher.last_packet()->header.frame_id;
  const auto released = batcher.add(with_frame_id(c.lidar[0], static_cast<uint16_t>(frame_id + 1)));
  ASSERT_TRUE(released.has_value());
  EXPECT_FALSE(released->complete);
  EXPECT_EQ(released->packets, 5u);
  EXPECT_EQ(released->frame_id, frame_id);
  // A packet of the released frame, or the one before it, is late: the SDK drops it.
  EXPECT_FALSE(batcher.add(c.lidar[6]).has_value());
  EXPECT_FALSE(batcher.add(with_frame_id(c.lidar[7], static_cast<uint16_t>(frame_id - 1))).has_value());
  EXPECT_EQ(batcher.counts().late, 2u);
  const auto open = batcher.flush();
  ASSERT_TRUE(open.has_value());
  EXPECT_EQ(open->frame_id, frame_id + 1);
  EXPECT_EQ(open->packets, 1u);
}

// SDK 1.0: an init_id change is a restart, even with the same frame_id (6.2).
TEST(ScanBatcher, AnInitIdChangeRestartsBatching) {
  const Capture c = load("windowed_frame1.pcap", "windowed_frame1_0.json");
  ScanBatcher batcher(c.metadata.format);
  for (size_t i = 0; i < 3; ++i) batcher.add(c.lidar[i]);
  const auto released = batcher.add(with_init_id(c.lidar[3], 0x00ABCD));
  ASSERT_TRUE(released.has_value());
  EXPECT_EQ(released->packets, 3u);
  EXPECT_FALSE(batcher.add(with_init_id(c.lidar[4], 0x00ABCD)).has_value());  // not late: a new session
  EXPECT_EQ(batcher.flush()->packets, 2u);
}

TEST(ScanBatcher, DropsWhatTheSdkDropsAndCountsIt) {
  const Capture c = load("windowed_frame1.pcap", "windowed_frame1_0.json");
  const Capture other = load("windowed_frame2.pcap", "windowed_frame2_0.json");  // the next session
  const auto& info = c.metadata.sensor_info;
  ScanBatcher batcher(c.metadata.format, SensorIds{info.initialization_id, std::stoull(info.prod_sn)});
  std::vector<uint8_t> short_packet(c.lidar[0].begin(), c.lidar[0].end() - 1);
  EXPECT_FALSE(batcher.add(short_packet).has_value());
  EXPECT_FALSE(batcher.add(other.lidar[0]).has_value());
  EXPECT_EQ(batcher.counts().wrong_size, 1u);
  EXPECT_EQ(batcher.counts().foreign, 1u);
  EXPECT_EQ(batcher.counts().batched, 0u);
  EXPECT_FALSE(batcher.flush().has_value());
}

}  // namespace
}  // namespace lidartwin
