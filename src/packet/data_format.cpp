// Enum <-> protocol strings (one table per enum), lidar modes and column windows (protocol doc 6).
#include "lidartwin/packet/data_format.h"

#include <algorithm>
#include <cassert>
#include <charconv>
#include <utility>

#include "packet/field_table.h"

namespace lidartwin {
namespace {

template <typename E, size_t N>
using NameTable = std::array<std::pair<E, std::string_view>, N>;

// Names exactly as in the metadata JSON and the SDK's string tables.
constexpr NameTable<UdpProfileLidar, 6> kLidarProfileNames{{
    {UdpProfileLidar::kLegacy, "LEGACY"},
    {UdpProfileLidar::kRng19Rfl8Sig16Nir16, "RNG19_RFL8_SIG16_NIR16"},
    {UdpProfileLidar::kRng15Rfl8Nir8, "RNG15_RFL8_NIR8"},
    {UdpProfileLidar::kRng19Rfl8Sig16Nir16Dual, "RNG19_RFL8_SIG16_NIR16_DUAL"},
    {UdpProfileLidar::kRng15Rfl8Nir8Dual, "RNG15_RFL8_NIR8_DUAL"},
    {UdpProfileLidar::kFusaRng15Rfl8Nir8Dual, "FUSA_RNG15_RFL8_NIR8_DUAL"},
}};

constexpr NameTable<UdpProfileImu, 3> kImuProfileNames{{
    {UdpProfileImu::kLegacy, "LEGACY"},
    {UdpProfileImu::kAccel32Gyro32Nmea, "ACCEL32_GYRO32_NMEA"},
    {UdpProfileImu::kOff, "OFF"},
}};

constexpr NameTable<HeaderType, 2> kHeaderTypeNames{{
    {HeaderType::kStandard, "STANDARD"},
    {HeaderType::kFusa, "FUSA"},
}};

constexpr NameTable<ChannelField, kChannelFieldCount> kChannelFieldNames{{
    {ChannelField::kRange, "RANGE"},
    {ChannelField::kFlags, "FLAGS"},
    {ChannelField::kReflectivity, "REFLECTIVITY"},
    {ChannelField::kSignal, "SIGNAL"},
    {ChannelField::kNearIr, "NEAR_IR"},
    {ChannelField::kWindow, "WINDOW"},
    {ChannelField::kRange2, "RANGE2"},
    {ChannelField::kFlags2, "FLAGS2"},
    {ChannelField::kReflectivity2, "REFLECTIVITY2"},
    {ChannelField::kSignal2, "SIGNAL2"},
}};

template <typename E, size_t N>
std::string_view lookup(const NameTable<E, N>& table, E value) {
  for (const auto& [e, name] : table) {
    if (e == value) return name;
  }
  assert(false && "enum value missing from its name table");
  return "UNKNOWN";
}

template <typename E, size_t N>
std::optional<E> rlookup(const NameTable<E, N>& table, std::string_view name) {
  for (const auto& [e, n] : table) {
    if (n == name) return e;
  }
  return std::nullopt;
}

// The modes the SDK knows (protocol doc 6.1).
constexpr std::array<LidarMode, 6> kLidarModes{{{512, 10}, {512, 20}, {1024, 10}, {1024, 20}, {2048, 10}, {4096, 5}}};

std::optional<int> parse_positive(std::string_view text) {
  int value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc{} || end != text.data() + text.size() || value <= 0) return std::nullopt;
  return value;
}

}  // namespace

std::string_view to_string(UdpProfileLidar profile) { return lookup(kLidarProfileNames, profile); }
std::string_view to_string(UdpProfileImu profile) { return lookup(kImuProfileNames, profile); }
std::string_view to_string(HeaderType type) { return lookup(kHeaderTypeNames, type); }
std::string_view to_string(ChannelField field) { return lookup(kChannelFieldNames, field); }

std::optional<UdpProfileLidar> udp_profile_lidar_from_string(std::string_view name) {
  return rlookup(kLidarProfileNames, name);
}
std::optional<UdpProfileImu> udp_profile_imu_from_string(std::string_view name) {
  return rlookup(kImuProfileNames, name);
}
std::optional<HeaderType> header_type_from_string(std::string_view name) { return rlookup(kHeaderTypeNames, name); }

std::vector<std::string_view> udp_profile_lidar_names() {
  std::vector<std::string_view> names;
  for (const auto& entry : kLidarProfileNames) names.push_back(entry.second);
  return names;
}

std::optional<LidarMode> parse_lidar_mode(std::string_view text) {
  const size_t x = text.find('x');
  if (x == std::string_view::npos) return std::nullopt;
  const auto width = parse_positive(text.substr(0, x));
  const auto fps = parse_positive(text.substr(x + 1));
  if (!width || !fps) return std::nullopt;
  const LidarMode mode{*width, *fps};
  if (std::find(kLidarModes.begin(), kLidarModes.end(), mode) == kLidarModes.end()) return std::nullopt;
  return mode;
}

std::string to_string(const LidarMode& mode) {
  return std::to_string(mode.columns_per_frame) + "x" + std::to_string(mode.fps);
}

// Protocol doc 6.4: an empirical fit to three real metadata files. Azimuth falls as m grows
// (theta = 360deg * (1 - m/W)), so the window's end gives the first column. Both ends are taken
// mod W (azimuth 0 and 360000 are column 0); a window that covers every column is reported as
// [0, W-1], as the FW does for the default [0, 360000].
std::array<int, 2> column_window_from_azimuth_window(int start_mdeg, int end_mdeg, int columns) {
  assert(columns > 0 && start_mdeg >= 0 && start_mdeg <= 360000 && end_mdeg >= 0 && end_mdeg <= 360000);
  const int64_t w = columns;
  const auto column_at = [w](int64_t mdeg) { return static_cast<int>(((360000 - mdeg) * w / 360000) % w); };
  const int first = (column_at(end_mdeg) + 1) % columns;
  const int last = column_at(start_mdeg);
  if ((last + 1) % columns == first) return {0, columns - 1};
  return {first, last};
}

bool column_in_window(const std::array<int, 2>& window, int m) {
  const auto [first, last] = window;
  return first <= last ? (m >= first && m <= last) : (m >= first || m <= last);
}

HeaderType implied_header_type(UdpProfileLidar profile) {
  return packet_detail::profile_spec(profile).header_type.value_or(HeaderType::kStandard);
}

HeaderType packet_header_type(const LidarDataFormat& format) {
  return packet_detail::profile_spec(format.udp_profile_lidar).header_type.value_or(format.header_type);
}

bool uses_fusa_header(const LidarDataFormat& format) { return packet_header_type(format) == HeaderType::kFusa; }

uint32_t frame_id_of(uint64_t frame_index, const LidarDataFormat& format) {
  if (uses_fusa_header(format)) return static_cast<uint32_t>(frame_index & 0xFFFF'FFFFu);
  return static_cast<uint32_t>(frame_index & 0xFFFFu);
}

}  // namespace lidartwin
