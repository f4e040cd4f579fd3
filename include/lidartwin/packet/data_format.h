#pragma once
// The shape of the data a sensor emits: lidar/IMU UDP profiles, header type, columns and pixels.
// This is the `lidar_data_format` section of the metadata as a value type (protocol doc 3.1, 4, 6).
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lidartwin {

enum class UdpProfileLidar {
  kLegacy,
  kRng19Rfl8Sig16Nir16,
  kRng15Rfl8Nir8,
  kRng19Rfl8Sig16Nir16Dual,
  kRng15Rfl8Nir8Dual,
  kFusaRng15Rfl8Nir8Dual,
};
enum class UdpProfileImu { kLegacy, kAccel32Gyro32Nmea, kOff };
enum class HeaderType { kStandard, kFusa };

// Enum <-> the exact strings of the protocol (one table each, in data_format.cpp).
std::string_view to_string(UdpProfileLidar profile);
std::string_view to_string(UdpProfileImu profile);
std::string_view to_string(HeaderType type);
std::optional<UdpProfileLidar> udp_profile_lidar_from_string(std::string_view name);
std::optional<UdpProfileImu> udp_profile_imu_from_string(std::string_view name);
std::optional<HeaderType> header_type_from_string(std::string_view name);
// All supported lidar profile names, for error messages ("expected one of …").
std::vector<std::string_view> udp_profile_lidar_names();

// "1024x10" -> {1024, 10}. Only the widths the SDK accepts (512/1024/2048/4096) and rates 5/10/20.
struct LidarMode {
  int columns_per_frame = 1024;
  int fps = 10;
  friend bool operator==(const LidarMode&, const LidarMode&) = default;
};
std::optional<LidarMode> parse_lidar_mode(std::string_view text);
std::string to_string(const LidarMode& mode);

// Per-pixel channels. Values are held in protocol units: range in mm (after the profile's upshift,
// so RNG15 ranges are multiples of 8), reflectivity 0-255, signal and near_ir in photons.
enum class ChannelField : uint8_t {
  kRange,
  kFlags,
  kReflectivity,
  kSignal,
  kNearIr,
  kWindow,
  kRange2,
  kFlags2,
  kReflectivity2,
  kSignal2,
  kCount,
};
inline constexpr int kChannelFieldCount = static_cast<int>(ChannelField::kCount);
std::string_view to_string(ChannelField field);

struct LidarDataFormat {
  UdpProfileLidar udp_profile_lidar = UdpProfileLidar::kLegacy;
  UdpProfileImu udp_profile_imu = UdpProfileImu::kLegacy;
  HeaderType header_type = HeaderType::kStandard;
  int pixels_per_column = 64;
  int columns_per_packet = 16;
  int columns_per_frame = 1024;
  int fps = 10;
  std::array<int, 2> column_window{0, 1023};  // inclusive measurement ids; wraps if [0] > [1]
  std::vector<int> pixel_shift_by_row;        // one per row
  int imu_measurements_per_packet = 0;        // ACCEL32_GYRO32_NMEA only
  int imu_packets_per_frame = 0;
  friend bool operator==(const LidarDataFormat&, const LidarDataFormat&) = default;
};

// Protocol doc 6.4: FW's azimuth_window [start, end] (millidegrees) -> column_window [c0, c1].
// Preconditions (asserted; validate config input first): 0 <= start, end <= 360000, columns > 0.
// A window covering every column comes back as [0, columns - 1].
std::array<int, 2> column_window_from_azimuth_window(int start_mdeg, int end_mdeg, int columns);
// Whether measurement id m lies inside the (possibly wrapping) window.
bool column_in_window(const std::array<int, 2>& window, int m);

// The header a lidar profile's packets carry unless lidar_data_format.header_type (FW 3.2) says
// otherwise: the field table's (FUSA_RNG15_RFL8_NIR8_DUAL fixes FUSA; the others: STANDARD).
HeaderType implied_header_type(UdpProfileLidar profile);
// The header packets of `format` carry: the profile's where it fixes one, else format.header_type.
HeaderType packet_header_type(const LidarDataFormat& format);
// Whether packets carry the FUSA header (4.3): its frame_id has 32 bits, the others 16.
bool uses_fusa_header(const LidarDataFormat& format);
// The frame_id of the n-th frame of a stream: +1 per revolution, wrapping at 2^16 or 2^32.
uint32_t frame_id_of(uint64_t frame_index, const LidarDataFormat& format);

}  // namespace lidartwin
