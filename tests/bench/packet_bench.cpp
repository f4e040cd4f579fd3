// Per-packet costs on the emulator's hot path (DESIGN.md "Speed"): CRC-64, encode and decode of
// one OS-128 packet. Reported as bytes/s of packet.
#include <random>
#include <span>
#include <vector>

#include <benchmark/benchmark.h>

#include "lidartwin/packet/lidar_packet.h"

namespace {

using lidartwin::LidarDataFormat;
using lidartwin::PacketFormat;
using lidartwin::Scan;

LidarDataFormat os128(lidartwin::UdpProfileLidar profile) {
  LidarDataFormat f;
  f.udp_profile_lidar = profile;
  f.pixels_per_column = 128;
  f.columns_per_frame = 2048;
  f.column_window = {0, 2047};
  return f;
}

// crc64_xz on OS-32 and OS-128 packet sizes.
void BM_Crc64(benchmark::State& state) {
  std::vector<uint8_t> data(static_cast<size_t>(state.range(0)));
  std::mt19937 rng(1);  // fixed seed: content does not matter for speed
  for (auto& b : data) b = static_cast<uint8_t>(rng());
  for (auto _ : state) benchmark::DoNotOptimize(lidartwin::crc64_xz(data));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * state.range(0));
}
BENCHMARK(BM_Crc64)->Arg(8448)->Arg(24832);

void BM_Encode(benchmark::State& state) {
  const auto f = os128(static_cast<lidartwin::UdpProfileLidar>(state.range(0)));
  const PacketFormat format(f);
  Scan scan(f);
  std::vector<uint8_t> packet(format.lidar_packet_size());
  int first = 0;
  for (auto _ : state) {
    format.encode(lidartwin::PacketHeader{}, scan, first, packet);
    first = (first + 16) % f.columns_per_frame;
    benchmark::DoNotOptimize(packet.data());
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * packet.size()));
}
BENCHMARK(BM_Encode)->Arg(0)->Arg(1)->Arg(2);

void BM_Decode(benchmark::State& state) {
  const auto f = os128(static_cast<lidartwin::UdpProfileLidar>(state.range(0)));
  const PacketFormat format(f);
  Scan scan(f);
  std::vector<uint8_t> packet(format.lidar_packet_size());
  format.encode(lidartwin::PacketHeader{}, scan, 0, packet);
  for (auto _ : state) benchmark::DoNotOptimize(format.decode(packet, scan, nullptr));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * packet.size()));
}
BENCHMARK(BM_Decode)->Arg(0)->Arg(1)->Arg(2);

}  // namespace

BENCHMARK_MAIN();
