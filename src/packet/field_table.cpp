// The tables, in the units of protocol doc 4.2-4.6: {field, {bit_offset, bit_width, upshift}}.
// Where the real sample captures (shared/data/ouster-samples) carry bits the doc does not list, the
// table follows the bytes so that decode -> encode reproduces a capture exactly; each case says so.
#include "packet/field_table.h"

#include <array>
#include <cassert>

namespace lidartwin::packet_detail {
namespace {

using CF = ChannelField;

// 4.2. REFLECTIVITY is 16 bits wide: SDK-1.0 reads bits 32-39 only, but SDK-0.x read a u16 at byte
// 4 and real FW 2.0 data uses the upper byte (OS-1-64_1024x10_fw20.pcap, OS-2-32-U0_v2.0.0).
constexpr std::array<ChannelSpec, 5> kLegacyChannels{{
    {CF::kRange, {0, 20}},
    {CF::kFlags, {28, 4}},
    {CF::kReflectivity, {32, 16}},
    {CF::kSignal, {48, 16}},
    {CF::kNearIr, {64, 16}},
}};

// 4.6. FLAGS spans bits 19-31: the doc lists 19-23, but real FW 2.3 sets bit 28 on no-return pixels
// (OS-2-128-U1_v2.3.0_1024x10.pcap, the LEGACY flag position), so the whole byte 3 is carried.
constexpr std::array<ChannelSpec, 6> kSingleChannels{{
    {CF::kRange, {0, 19}},
    {CF::kFlags, {19, 13}},
    {CF::kReflectivity, {32, 8}},
    {CF::kSignal, {48, 16}},
    {CF::kNearIr, {64, 16}},
    {CF::kWindow, {88, 8}},
}};

constexpr std::array<ChannelSpec, 4> kLowDataRateChannels{{
    {CF::kRange, {0, 15, 3}},
    {CF::kFlags, {15, 1}},
    {CF::kReflectivity, {16, 8}},
    {CF::kNearIr, {24, 8, 4}},
}};

constexpr std::array<ChannelSpec, 10> kDualChannels{{
    {CF::kRange, {0, 19}},
    {CF::kFlags, {19, 5}},
    {CF::kReflectivity, {24, 8}},
    {CF::kRange2, {32, 19}},
    {CF::kFlags2, {51, 5}},
    {CF::kReflectivity2, {56, 8}},
    {CF::kSignal, {64, 16}},
    {CF::kSignal2, {80, 16}},
    {CF::kNearIr, {96, 16}},
    {CF::kWindow, {120, 8}},
}};

constexpr std::array<ChannelSpec, 8> kLowDataRateDualChannels{{
    {CF::kRange, {0, 15, 3}},
    {CF::kFlags, {15, 1}},
    {CF::kReflectivity, {16, 8}},
    {CF::kNearIr, {24, 8, 4}},
    {CF::kRange2, {32, 15, 3}},
    {CF::kFlags2, {47, 1}},
    {CF::kReflectivity2, {48, 8}},
    {CF::kWindow, {56, 8}},
}};

// 4.2: the column header; the status word is the 4-byte column footer after the pixels.
constexpr std::array<ColumnSpec, 4> kLegacyColumnHeader{{
    {ColumnField::kTimestamp, {0, 64}},
    {ColumnField::kMeasurementId, {64, 16}},
    {ColumnField::kFrameId, {80, 16}},
    {ColumnField::kEncoderCount, {96, 32}},
}};
constexpr std::array<ColumnSpec, 1> kLegacyColumnFooter{{{ColumnField::kStatus, {0, 32}}}};

// 4.4
constexpr std::array<ColumnSpec, 3> kColumnHeader{{
    {ColumnField::kTimestamp, {0, 64}},
    {ColumnField::kMeasurementId, {64, 16}},
    {ColumnField::kStatus, {80, 16}},
}};

constexpr PacketLayout kLegacyLayout{0, 16, kLegacyColumnHeader, 4, kLegacyColumnFooter, 0, false};
// 4.3-4.5
constexpr PacketLayout kStandardLayout{32, 12, kColumnHeader, 0, {}, 32, true};

using HF = HeaderField;

// 4.3. Status nibbles are the low ones (SDK-1.0 and real FW 3.2 shot_limiting_test.pcap).
constexpr std::array<HeaderSpec, 9> kStandardHeader{{
    {HF::kPacketType, {0, 16}},
    {HF::kFrameId, {16, 16}},
    {HF::kInitId, {32, 24}},
    {HF::kProdSn, {56, 40}},
    {HF::kAlertFlags, {96, 8}},
    {HF::kCountdownThermalShutdown, {128, 8}},
    {HF::kCountdownShotLimiting, {136, 8}},
    {HF::kThermalShutdown, {144, 4}},
    {HF::kShotLimiting, {152, 4}},
}};

// 4.3, FUSA: checked on OS-1-128_767798045_1024x10_20230712_120049.pcap.
constexpr std::array<HeaderSpec, 9> kFusaHeader{{
    {HF::kPacketType, {0, 8}},
    {HF::kInitId, {8, 24}},
    {HF::kFrameId, {32, 32}},
    {HF::kAlertFlags, {64, 8}},
    {HF::kProdSn, {88, 40}},
    {HF::kCountdownThermalShutdown, {128, 8}},
    {HF::kCountdownShotLimiting, {136, 8}},
    {HF::kThermalShutdown, {144, 4}},
    {HF::kShotLimiting, {152, 4}},
}};

using P = UdpProfileLidar;
constexpr std::array<ProfileSpec, 6> kProfiles{{
    {P::kLegacy, 12, kLegacyChannels, &kLegacyLayout, std::nullopt},
    {P::kRng19Rfl8Sig16Nir16, 12, kSingleChannels, &kStandardLayout, std::nullopt},
    {P::kRng15Rfl8Nir8, 4, kLowDataRateChannels, &kStandardLayout, std::nullopt},
    {P::kRng19Rfl8Sig16Nir16Dual, 16, kDualChannels, &kStandardLayout, std::nullopt},
    {P::kRng15Rfl8Nir8Dual, 8, kLowDataRateDualChannels, &kStandardLayout, std::nullopt},
    {P::kFusaRng15Rfl8Nir8Dual, 8, kLowDataRateDualChannels, &kStandardLayout, HeaderType::kFusa},
}};

// Compile-time checks of every table: fields lie inside their struct, fit one 64-bit access, and
// do not overlap; pixel fields stay inside one aligned 32-bit word.
template <typename Spec>
constexpr bool fields_fit(std::span<const Spec> specs, int struct_bytes) {
  for (size_t i = 0; i < specs.size(); ++i) {
    const FieldSpec a = specs[i].bits;
    if (a.bit_width < 1 || a.bit_offset % 8 + a.bit_width > 64 || a.bit_width + a.upshift > 64) return false;
    if (a.bit_offset < 0 || a.bit_offset + a.bit_width > struct_bytes * 8) return false;
    for (size_t j = 0; j < i; ++j) {
      const FieldSpec b = specs[j].bits;
      if (a.bit_offset < b.bit_offset + b.bit_width && b.bit_offset < a.bit_offset + a.bit_width) return false;
    }
  }
  return true;
}

// Pixel fields stay inside one aligned 32-bit word (and so one 64-bit word): the encoder builds
// pixels as planes of 32-bit words (packet_encode.cpp). True of every Ouster profile.
constexpr bool within_32_bit_words(std::span<const ChannelSpec> specs) {
  for (const ChannelSpec& s : specs) {
    if (s.bits.bit_offset / 32 != (s.bits.bit_offset + s.bits.bit_width - 1) / 32) return false;
  }
  return true;
}

constexpr bool tables_valid() {
  for (const ProfileSpec& p : kProfiles) {
    if (!fields_fit(p.channels, p.pixel_bytes) || !within_32_bit_words(p.channels)) return false;
    if (p.pixel_bytes > kMaxPixelBytes) return false;
  }
  for (const PacketLayout* l : {&kLegacyLayout, &kStandardLayout}) {
    if (!fields_fit(l->column_header, l->column_header_bytes)) return false;
    if (!fields_fit(l->column_footer, l->column_footer_bytes)) return false;
    if (l->crc_footer && l->packet_footer_bytes < kCrcBytes) return false;
  }
  return fields_fit(std::span<const HeaderSpec>(kStandardHeader), kStandardLayout.packet_header_bytes) &&
         fields_fit(std::span<const HeaderSpec>(kFusaHeader), kStandardLayout.packet_header_bytes);
}
static_assert(tables_valid(), "a packet field table is inconsistent");

constexpr bool profiles_in_enum_order() {
  for (size_t i = 0; i < kProfiles.size(); ++i) {
    if (static_cast<size_t>(kProfiles[i].profile) != i) return false;
  }
  return true;
}
static_assert(profiles_in_enum_order(), "kProfiles is indexed by UdpProfileLidar");

}  // namespace

const ProfileSpec& profile_spec(UdpProfileLidar profile) {
  const auto index = static_cast<size_t>(profile);
  assert(index < kProfiles.size());
  return kProfiles[index];
}

std::span<const HeaderSpec> header_spec(HeaderType type) {
  return type == HeaderType::kFusa ? std::span<const HeaderSpec>(kFusaHeader)
                                   : std::span<const HeaderSpec>(kStandardHeader);
}

}  // namespace lidartwin::packet_detail
