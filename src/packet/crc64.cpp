// CRC-64/XZ (protocol doc 4.5): reflected ECMA-182 polynomial, init and final XOR all ones.
// It runs over every packet sent (~25 KB, over a thousand per second per sensor), so it is
// table-sliced by 16: sixteen table lookups consume 16 bytes per step instead of one lookup per byte.
#include <array>
#include <cstring>

#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin {
namespace {

constexpr uint64_t kPolyReflected = 0xC96C5795D7870F42ull;
constexpr int kSlices = 16;
using Tables = std::array<std::array<uint64_t, 256>, kSlices>;

// tables[0] is the classic byte-at-a-time table; tables[k][b] is the CRC of byte b followed by k
// zero bytes, so the k-th byte before the end of a block is looked up in tables[k].
constexpr Tables make_tables() {
  Tables t{};
  for (uint64_t b = 0; b < 256; ++b) {
    uint64_t crc = b;
    for (int bit = 0; bit < 8; ++bit) crc = (crc & 1) ? (crc >> 1) ^ kPolyReflected : crc >> 1;
    t[0][b] = crc;
  }
  for (size_t k = 1; k < kSlices; ++k) {
    for (size_t b = 0; b < 256; ++b) t[k][b] = (t[k - 1][b] >> 8) ^ t[0][t[k - 1][b] & 0xFF];
  }
  return t;
}
constexpr Tables kTables = make_tables();

uint64_t load64(const uint8_t* p) {
  uint64_t v = 0;
  std::memcpy(&v, p, 8);  // little-endian host (static_assert in field_codec.h)
  return v;
}

uint64_t lookup8(uint64_t word, size_t first_table) {
  uint64_t r = 0;
  for (size_t i = 0; i < 8; ++i) r ^= kTables[first_table - i][(word >> (8 * i)) & 0xFF];
  return r;
}

}  // namespace

uint64_t crc64_xz(std::span<const uint8_t> bytes) {
  uint64_t crc = ~uint64_t{0};
  const uint8_t* p = bytes.data();
  size_t n = bytes.size();
  for (; n >= kSlices; n -= kSlices, p += kSlices) {
    crc = lookup8(crc ^ load64(p), kSlices - 1) ^ lookup8(load64(p + 8), kSlices / 2 - 1);
  }
  for (; n > 0; --n, ++p) crc = kTables[0][(crc ^ *p) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

}  // namespace lidartwin
