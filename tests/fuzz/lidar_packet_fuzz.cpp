// libFuzzer: a lidar packet as the daemon's clients' side decodes it (PacketFormat::decode), for
// every UDP profile at 16 and 128 beams. Byte 0 picks the format; with its top bit set the rest is
// cut or padded to that format's exact packet size, so mutations reach past the size check.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "lidartwin/packet/lidar_packet.h"
#include "packet_test_util.h"

namespace {
using namespace lidartwin;

// Each format with a scan to decode into, made once: a fresh scan per input would cost more than
// the decoding (64 columns a frame keep it small).
struct Format {
  LidarDataFormat data;
  PacketFormat packet;
  Scan scan;
  explicit Format(const LidarDataFormat& f) : data(f), packet(f), scan(f) {}
};

std::vector<Format>& formats() {
  static std::vector<Format> all = [] {
    std::vector<Format> out;
    for (UdpProfileLidar profile : test::kProfiles) {
      for (int height : {16, 128}) out.emplace_back(test::make_format(profile, height, 16, 64));
    }
    return out;
  }();
  return all;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  Format& format = formats()[data[0] % formats().size()];
  std::vector<uint8_t> packet(data + 1, data + size);
  if (data[0] & 0x80) packet.resize(format.packet.lidar_packet_size());
  Scan& scan = format.scan;
  std::string error;
  if (format.packet.decode(packet, scan, &error)) {
    // Decoded channels hold only what their fields can carry.
    for (int f = 0; f < kChannelFieldCount; ++f) {
      const auto field = static_cast<ChannelField>(f);
      if (!format.packet.has_channel(field)) continue;
      for (const uint32_t v : scan.channels[static_cast<size_t>(f)]) {
        if (v > format.packet.channel_max(field)) __builtin_trap();
      }
    }
  } else if (error.empty()) {
    __builtin_trap();  // a refusal says why
  }
  return 0;
}
