// CRC-64/XZ (protocol doc 4.5): reflected ECMA-182 polynomial, init and final XOR all ones.
// It runs over every packet sent (~25 KB, over a thousand per second per sensor per frame rate),
// so on x86-64 CPUs with PCLMULQDQ it folds 64 bytes per step with carry-less multiplies (the
// method of Gopal et al., "Fast CRC computation for generic polynomials using PCLMULQDQ", Intel
// 2009), about five times the table method. Elsewhere, and for short inputs and the last bytes,
// a table sliced by 16 consumes 16 bytes per step instead of one lookup per byte.
#include <array>
#include <cstring>

#include "lidartwin/packet/lidar_packet.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define LIDARTWIN_CRC_CLMUL 1
#include <immintrin.h>
#endif

namespace lidartwin {
namespace {

constexpr uint64_t kPoly = 0x42F0E1EBA9EA3693ull;  // x^64 implicit
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

// The reflected CRC register after `n` more bytes: register = (register·x^8n + bytes·x^64) mod P.
uint64_t update_tables(uint64_t crc, const uint8_t* p, size_t n) {
  for (; n >= kSlices; n -= kSlices, p += kSlices) {
    crc = lookup8(crc ^ load64(p), kSlices - 1) ^ lookup8(load64(p + 8), kSlices / 2 - 1);
  }
  for (; n > 0; --n, ++p) crc = kTables[0][(crc ^ *p) & 0xFF] ^ (crc >> 8);
  return crc;
}

#ifdef LIDARTWIN_CRC_CLMUL

// x^e mod P, bit-reversed into the reflected convention (bit i holds the coefficient of x^(63-i)).
constexpr uint64_t reflected_power(int e) {
  uint64_t r = 1;
  for (int i = 0; i < e; ++i) r = (r & (1ull << 63)) ? (r << 1) ^ kPoly : r << 1;
  uint64_t reflected = 0;
  for (int i = 0; i < 64; ++i) reflected |= ((r >> i) & 1) << (63 - i);
  return reflected;
}

// A 16-byte block loaded little-endian holds, in its low quadword, the first 64 message bits H
// (coefficients of x^127..x^64 of the block) and in its high quadword the next 64, L. Moving the
// block F bits further down the message multiplies it by x^F: H·x^(F+64) + L·x^F, each reduced by
// one carry-less multiply with a 64-bit constant. A reflected product comes out one bit low
// (it represents a·b·x), so the constants are x^(F+63) and x^(F-1) mod P.
struct FoldConstants {
  uint64_t for_low;   // multiplies H: x^(F+63) mod P
  uint64_t for_high;  // multiplies L: x^(F-1) mod P
};
constexpr FoldConstants fold_by(int bits) { return {reflected_power(bits + 63), reflected_power(bits - 1)}; }
constexpr FoldConstants kFold512 = fold_by(512), kFold384 = fold_by(384), kFold256 = fold_by(256),
                        kFold128 = fold_by(128);

__attribute__((target("pclmul,sse2"))) inline __m128i fold(__m128i x, FoldConstants k) {
  const __m128i constants = _mm_set_epi64x(static_cast<long long>(k.for_high), static_cast<long long>(k.for_low));
  return _mm_xor_si128(_mm_clmulepi64_si128(x, constants, 0x00), _mm_clmulepi64_si128(x, constants, 0x11));
}

__attribute__((target("pclmul,sse2"))) inline __m128i load128(const uint8_t* p) {
  return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
}

// n >= 64. Four 16-byte lanes fold 64 bytes per step; then the lanes fold into one, which takes
// the remaining whole blocks. The last 128-bit remainder R stands for R·x^64 mod P, which is the
// table CRC of its 16 bytes from a zero register; the bytes after it continue from there.
__attribute__((target("pclmul,sse2"))) uint64_t update_clmul(uint64_t crc, const uint8_t* p, size_t n) {
  __m128i lane[4] = {load128(p), load128(p + 16), load128(p + 32), load128(p + 48)};
  lane[0] = _mm_xor_si128(lane[0], _mm_set_epi64x(0, static_cast<long long>(crc)));  // the register meets the first bytes
  p += 64;
  n -= 64;
  for (; n >= 64; n -= 64, p += 64) {
    for (int i = 0; i < 4; ++i) lane[i] = _mm_xor_si128(fold(lane[i], kFold512), load128(p + 16 * i));
  }
  __m128i x = _mm_xor_si128(_mm_xor_si128(fold(lane[0], kFold384), fold(lane[1], kFold256)),
                            _mm_xor_si128(fold(lane[2], kFold128), lane[3]));
  for (; n >= 16; n -= 16, p += 16) x = _mm_xor_si128(fold(x, kFold128), load128(p));
  alignas(16) uint8_t rest[16];
  _mm_store_si128(reinterpret_cast<__m128i*>(rest), x);
  return update_tables(update_tables(0, rest, 16), p, n);
}

bool cpu_has_clmul() {
  static const bool has = __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse2");
  return has;
}

#endif

}  // namespace

uint64_t crc64_xz(std::span<const uint8_t> bytes) {
  constexpr uint64_t kInit = ~uint64_t{0};
#ifdef LIDARTWIN_CRC_CLMUL
  if (bytes.size() >= 64 && cpu_has_clmul()) return ~update_clmul(kInit, bytes.data(), bytes.size());
#endif
  return ~update_tables(kInit, bytes.data(), bytes.size());
}

uint64_t crc64_xz_tables(std::span<const uint8_t> bytes) {
  return ~update_tables(~uint64_t{0}, bytes.data(), bytes.size());
}

}  // namespace lidartwin
