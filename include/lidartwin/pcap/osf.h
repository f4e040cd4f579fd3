#pragma once
// OSF files: ouster-cli's recordings (`ouster-cli source SENSOR save x.osf`), which carry the
// sensor's metadata JSON and its lidar data as LidarScans (whole frames), not packets. Read here
// beside pcap because both are how captures reach lidartwin; turning a scan into the analysis's
// frames is the analysis's business (it knows the metadata).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lidartwin {

// Whether the file starts as an OSF file does (a size-prefixed header with identifier "OSF$"),
// whatever its name.
bool is_osf_file(const std::filesystem::path& path);
// Whether a capture is to be read as OSF (is_osf_file) rather than left to the pcap reader. Throws
// InputError for a file named *.osf that has no OSF header, which the pcap reader would only call
// an unknown format.
bool read_as_osf(const std::filesystem::path& path);

// The per-pixel fields of a LidarScan, numbered as OSF numbers them (CHAN_FIELD in ouster-sdk 1.0.1,
// ouster_osf/fb/os_sensor/lidar_scan_stream.fbs). Others (custom fields, raw words) are not read.
enum class OsfField : uint8_t {
  kRange = 1,
  kRange2 = 2,
  kSignal = 3,
  kSignal2 = 4,
  kReflectivity = 5,
  kReflectivity2 = 6,
  kNearIr = 7,
  kFlags = 8,
  kFlags2 = 9,
};
std::string to_string(OsfField field);  // "RANGE", "NEAR_IR", ... as the SDK names them

struct OsfImage {
  OsfField field = OsfField::kRange;
  std::vector<uint32_t> values;  // row-major, H x W: element r * width + c
  // As the SDK stores PNG fields (not ZPNG ones): column m of row r measured is then at column
  // (m + pixel_shift_by_row[r]) mod W; otherwise at column m, as packets carry it.
  bool destaggered = false;
};

// One LidarScan message of the lidar stream, in the sensor's units (range in mm, after the packet
// profile's upshift).
struct OsfScan {
  uint64_t receive_ns = 0;  // when the writer got it (host clock)
  int32_t frame_id = 0;
  int width = 0;
  int height = 0;
  std::vector<uint64_t> column_timestamp_ns;  // [W], by measurement id; 0 where no packet came
  std::vector<uint16_t> measurement_id;       // [W]
  std::vector<uint32_t> column_status;        // [W], bit 0 = valid
  std::vector<uint64_t> packet_timestamp_ns;  // [W / columns_per_packet] or empty if not written
  std::vector<OsfImage> images;               // the fields of OsfField the scan holds
};

// A metadata entry, for summaries: "ouster/v1/os_sensor/LidarScanStream" etc.
struct OsfEntry {
  uint32_t id = 0;
  std::string type;
};

struct OsfFileInfo {
  uint64_t version = 0;               // as stored: 20 (2.0), 21 (2.1), or major << 48 | minor << 32 | patch << 16
  std::string version_name;           // "2.1"
  bool finished = true;               // the header's status says the writer closed the file
  std::string writer;                 // the metadata's id ("ouster_sdk")
  uint64_t start_ns = 0, end_ns = 0;  // receive times of the first and last message
  std::vector<OsfEntry> entries;
  size_t lidar_streams = 0;      // LidarScanStream entries
  uint32_t lidar_stream_id = 0;  // the one read
  std::string sensor_metadata;   // the JSON of the LidarSensor the read stream belongs to
};

// Reads an OSF file: its header and metadata on construction, then the chosen lidar stream's scans
// one at a time, chunk by chunk, so a recording larger than memory can be read. Throws InputError
// naming the file and the problem: not an OSF file, truncated, an unsupported version (1.x, or a
// major version above 2), a broken header or chunk (CRC, flatbuffer), no lidar stream, a field
// encoded other than as PNG or ZPNG. Never crashes on hostile input.
class OsfReader {
 public:
  // lidar_stream: which LidarScanStream to read (0: the first, in metadata order) when the file
  // holds several sensors.
  explicit OsfReader(const std::filesystem::path& path, size_t lidar_stream = 0);
  ~OsfReader();
  OsfReader(const OsfReader&) = delete;
  OsfReader& operator=(const OsfReader&) = delete;

  const OsfFileInfo& info() const;
  // The next scan of the lidar stream, or nullopt at the end of the file.
  std::optional<OsfScan> next();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidartwin
