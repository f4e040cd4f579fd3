#pragma once
// One bit field of a packet, both directions (STYLE.md section 3): the decoder uses get, the encoder
// set, and both read the same {offset, mask, shift}. Access is a memcpy over a bounded span, never
// past its end (the SDK's FieldDecodeInfo reads 8 bytes past the field start unconditionally).
#include <bit>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

namespace lidartwin::packet_detail {

// Every packet field is little-endian (protocol doc 0); a load of the host word is the field word.
static_assert(std::endian::native == std::endian::little, "packet codecs assume a little-endian host");

// A field as the protocol doc writes it: bit position from the start of its struct (bit 0 = LSB of
// byte 0), width in bits, and the upshift from packet value to protocol units (RNG15 range: 3).
struct FieldSpec {
  int bit_offset = 0;
  int bit_width = 0;
  int upshift = 0;
};

struct FieldCodec {
  uint32_t offset = 0;  // first byte, relative to the span handed to get/set
  uint32_t bytes = 0;   // bytes the field touches (1..8); 0 = absent field
  uint64_t mask = 0;    // field bits within the little-endian word at offset
  int shift = 0;        // (word & mask) >> shift, or << -shift, = value in protocol units
  int upshift = 0;      // value = packet bits << upshift (FieldSpec)

  static constexpr FieldCodec from(FieldSpec spec, int base_byte = 0) {
    return make(base_byte + spec.bit_offset / 8, spec.bit_offset % 8, spec);
  }

  // The same field addressed from the start of its aligned 64-bit word (offset a multiple of 8),
  // for pixels handled a word at a time (packet_encode.cpp). The field must not cross a word.
  static constexpr FieldCodec in_word(FieldSpec spec) {
    assert(spec.bit_offset / 64 == (spec.bit_offset + spec.bit_width - 1) / 64);
    return make(spec.bit_offset / 64 * 8, spec.bit_offset % 64, spec);
  }

  bool present() const { return bytes != 0; }
  // Largest value in protocol units, and the step between representable values.
  uint64_t max_value() const { return from_word(mask); }
  uint64_t step() const { return uint64_t{1} << upshift; }

  uint64_t get(std::span<const uint8_t> buf) const { return extract(load(buf)); }

  // Bits of value beyond the field are a caller bug; they are masked off so neighbours stay intact.
  // Bits below the step (an RNG15 range that is not a multiple of 8 mm) are truncated, as the
  // packet cannot carry them.
  void set(std::span<uint8_t> buf, uint64_t value) const {
    assert(fits(value));
    store(buf, (load(buf) & ~mask) | place(value));
  }

  // Whether value survives the field apart from the bits below its step.
  bool fits(uint64_t value) const { return extract(place(value)) == (value & ~(step() - 1)); }

  // The field's value from the little-endian word at offset, and back.
  uint64_t extract(uint64_t word) const { return from_word(word & mask); }
  uint64_t place(uint64_t value) const { return to_word(value) & mask; }

 private:
  // Table entries are checked at compile time (field_table.cpp), so this only asserts.
  static constexpr FieldCodec make(int byte, int bit, FieldSpec spec) {
    assert(byte >= 0 && spec.bit_width >= 1 && bit + spec.bit_width <= 64 && spec.bit_width + spec.upshift <= 64);
    FieldCodec codec;
    codec.offset = static_cast<uint32_t>(byte);
    codec.bytes = static_cast<uint32_t>((bit + spec.bit_width + 7) / 8);
    codec.mask = (spec.bit_width == 64 ? ~uint64_t{0} : (uint64_t{1} << spec.bit_width) - 1) << bit;
    codec.shift = bit - spec.upshift;
    codec.upshift = spec.upshift;
    return codec;
  }

  uint64_t from_word(uint64_t word) const { return shift >= 0 ? word >> shift : word << -shift; }
  uint64_t to_word(uint64_t value) const { return shift >= 0 ? value << shift : value >> -shift; }

  // A full 8-byte access when the span allows it (one load), else only the field's bytes.
  uint64_t load(std::span<const uint8_t> buf) const {
    assert(offset + bytes <= buf.size());
    uint64_t word = 0;
    if (buf.size() - offset >= 8) {
      std::memcpy(&word, buf.data() + offset, 8);
    } else {
      std::memcpy(&word, buf.data() + offset, bytes);
    }
    return word;
  }
  void store(std::span<uint8_t> buf, uint64_t word) const {
    if (buf.size() - offset >= 8) {
      std::memcpy(buf.data() + offset, &word, 8);
    } else {
      std::memcpy(buf.data() + offset, &word, bytes);
    }
  }
};

}  // namespace lidartwin::packet_detail
