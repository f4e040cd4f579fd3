// OSF files (ouster-sdk 1.0.1's layout, "STREAMING" chunks): a header block at offset 0, chunk
// blocks after it, the metadata block at the header's metadata_offset. Every block is
// [u32 size][size-prefixed flatbuffer body][u32 CRC-32 of the size and body], little-endian
// (ouster_osf/src/basics.cpp). Chunks are read in file order; a stream's messages are in time order.
#include <algorithm>
#include <array>
#include <cstring>
#include <fstream>
#include <map>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "lidartwin/error.h"
#include "lidartwin/pcap/osf.h"
#include "pcap/osf_scan_message.h"
#include "pcap/osf_tables.h"

namespace lidartwin {
namespace {

using namespace osf_detail;
namespace fs = std::filesystem;

constexpr size_t kPrefixBytes = 4, kCrcBytes = 4;
constexpr uint8_t kHeaderValid = 2;  // HEADER_STATUS VALID: the writer closed the file
constexpr const char* kLidarSensorType = "ouster/v1/os_sensor/LidarSensor";
constexpr const char* kLidarScanStreamType = "ouster/v1/os_sensor/LidarScanStream";

uint32_t little32(const uint8_t* p) {
  return uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24);
}

// CRC-32 (IEEE 802.3, reflected 0xEDB88320), as zlib's crc32 and the SDK's osf::crc32 compute it.
uint32_t crc32(const uint8_t* data, size_t size) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t n = 0; n < 256; ++n) {
      uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < size; ++i) crc = table[(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
  return crc ^ 0xFFFFFFFFu;
}

// The stored version as major.minor: 20 and 21 are 2.0 and 2.1 (ouster_osf's OsfVersion enum), 1-5
// the 1.x versions before them, anything larger major << 48 | minor << 32 | patch << 16
// (ouster_osf/src/file.cpp).
std::pair<uint64_t, uint64_t> major_minor(uint64_t version) {
  if (version == 20) return {2, 0};
  if (version == 21) return {2, 1};
  if (version < 20) return {1, version == 0 ? 0 : version - 1};
  return {version >> 48, (version >> 32) & 0xFFFFu};
}

std::string text_of(const fb::String* s) { return s ? s->str() : std::string(); }

}  // namespace

std::string to_string(OsfField field) {
  switch (field) {
    case OsfField::kRange: return "RANGE";
    case OsfField::kRange2: return "RANGE2";
    case OsfField::kSignal: return "SIGNAL";
    case OsfField::kSignal2: return "SIGNAL2";
    case OsfField::kReflectivity: return "REFLECTIVITY";
    case OsfField::kReflectivity2: return "REFLECTIVITY2";
    case OsfField::kNearIr: return "NEAR_IR";
    case OsfField::kFlags: return "FLAGS";
    case OsfField::kFlags2: return "FLAGS2";
  }
  return "UNKNOWN";
}

bool is_osf_file(const fs::path& path) {
  std::array<char, 12> head{};
  std::ifstream in(path, std::ios::binary);
  in.read(head.data(), head.size());
  // The block's size prefix, the flatbuffer's root offset, then its identifier.
  return in.gcount() == 12 && std::memcmp(head.data() + 8, "OSF$", 4) == 0;
}

bool read_as_osf(const fs::path& path) {
  if (is_osf_file(path)) return true;
  if (path.extension() == ".osf" && fs::is_regular_file(path)) {
    throw InputError(path.string() + ": not an OSF file (it does not start with an OSF header, identifier \"OSF$\")");
  }
  return false;
}

struct OsfReader::Impl {
  fs::path path;
  std::ifstream in;
  uint64_t file_size = 0;
  uint64_t chunks_end = 0;  // where the metadata block starts
  uint64_t next_chunk = 0;  // offset of the next chunk block to read
  std::vector<uint8_t> chunk;
  const ChunkTable* chunk_table = nullptr;
  size_t next_message = 0;
  size_t scans = 0;   // of the lidar stream, read so far
  size_t wanted = 0;  // which lidar stream
  OsfFileInfo info;

  [[noreturn]] void fail(const std::string& why) const { throw InputError(path.string() + ": " + why); }

  // The block at `offset`, which must end by `limit`, with its CRC checked.
  std::vector<uint8_t> read_block(uint64_t offset, uint64_t limit, const std::string& what) {
    if (offset + kPrefixBytes > limit) {
      fail(fmt::format("truncated: {} at byte {} is cut off (the file has {} bytes)", what, offset, file_size));
    }
    std::array<uint8_t, kPrefixBytes> prefix{};
    in.seekg(static_cast<std::streamoff>(offset));
    in.read(reinterpret_cast<char*>(prefix.data()), kPrefixBytes);
    const uint64_t total = kPrefixBytes + uint64_t{little32(prefix.data())} + kCrcBytes;
    if (!in || offset + total > limit) {
      fail(fmt::format("truncated: {} at byte {} needs {} bytes, {} remain", what, offset, total,
                       limit > offset ? limit - offset : 0));
    }
    std::vector<uint8_t> block(total);
    std::memcpy(block.data(), prefix.data(), kPrefixBytes);
    in.read(reinterpret_cast<char*>(block.data() + kPrefixBytes), static_cast<std::streamsize>(total - kPrefixBytes));
    if (!in) fail(fmt::format("could not read {} at byte {}", what, offset));
    if (crc32(block.data(), total - kCrcBytes) != little32(block.data() + total - kCrcBytes)) {
      fail(fmt::format("{} at byte {} fails its CRC-32: the file is damaged", what, offset));
    }
    return block;
  }

  void read_header() {
    std::vector<uint8_t> block = read_block(0, file_size, "the OSF header");
    const auto* header = verified_root<HeaderTable>(block.data(), block.size() - kCrcBytes, "OSF$");
    if (!header) fail("not an OSF file (no valid \"OSF$\" header at its start)");
    info.version = header->version();
    const auto [major, minor] = major_minor(info.version);
    info.version_name = fmt::format("{}.{}", major, minor);
    if (major != 2) {
      fail(
          fmt::format("OSF version {} is not supported (lidartwin reads OSF 2.x, as ouster-sdk 0.11 and later "
                      "write it)",
                      info.version_name));
    }
    info.finished = header->status() == kHeaderValid;
    next_chunk = block.size();
    chunks_end = header->metadata_offset();
    const uint64_t length = header->file_length();
    if (!info.finished) {
      fail(
          "the recording was not finished (its header is not marked valid: the writer stopped before "
          "writing the metadata)");
    }
    if (length > file_size) {
      fail(fmt::format("truncated: its header says {} bytes, the file has {}", length, file_size));
    }
    if (chunks_end < next_chunk || chunks_end >= length) {
      fail(fmt::format("its header puts the metadata at byte {}, outside the file's {} bytes", chunks_end, length));
    }
    read_metadata(length);
  }

  void read_metadata(uint64_t length) {
    std::vector<uint8_t> block = read_block(chunks_end, length, "the metadata block");
    const auto* meta = verified_root<MetadataTable>(block.data(), block.size() - kCrcBytes, "OSF#");
    if (!meta) fail(fmt::format("the metadata block at byte {} is not a valid OSF metadata flatbuffer", chunks_end));
    info.writer = text_of(meta->writer());
    info.start_ns = meta->start_ns();
    info.end_ns = meta->end_ns();
    std::map<uint32_t, std::string> sensors;             // LidarSensor entry id -> metadata JSON
    std::vector<std::pair<uint32_t, uint32_t>> streams;  // (stream entry id, sensor entry id)
    if (meta->entries()) {
      for (const MetadataEntryTable* entry : *meta->entries()) {
        OsfEntry e{entry->id(), text_of(entry->type())};
        const fb::Vector<uint8_t>* buffer = entry->buffer();
        const uint8_t* data = buffer ? buffer->data() : nullptr;
        const size_t size = buffer ? buffer->size() : 0;
        if (e.type == kLidarSensorType) {
          const auto* sensor = verified_root<LidarSensorTable>(data, size, "oLS_");
          if (!sensor) fail(fmt::format("metadata entry {} ({}) is not a valid LidarSensor", e.id, e.type));
          sensors[e.id] = text_of(sensor->metadata());
        } else if (e.type == kLidarScanStreamType) {
          const auto* stream =
              verified_root<LidarScanStreamTable>(data, size, nullptr);  // written without its identifier
          if (!stream) fail(fmt::format("metadata entry {} ({}) is not a valid LidarScanStream", e.id, e.type));
          streams.emplace_back(e.id, stream->sensor_id());
        }
        info.entries.push_back(std::move(e));
      }
    }
    choose_stream(sensors, streams);
  }

  void choose_stream(const std::map<uint32_t, std::string>& sensors,
                     const std::vector<std::pair<uint32_t, uint32_t>>& streams) {
    info.lidar_streams = streams.size();
    if (streams.empty()) {
      std::vector<std::string> types;
      for (const OsfEntry& e : info.entries) types.push_back(e.type);
      fail(fmt::format("no lidar stream (no {} entry; its metadata holds: {})", kLidarScanStreamType,
                       types.empty() ? std::string("nothing") : fmt::format("{}", fmt::join(types, ", "))));
    }
    if (wanted >= streams.size()) {
      fail(fmt::format("it holds {} lidar stream{}, there is no stream {}", streams.size(),
                       streams.size() == 1 ? "" : "s", wanted));
    }
    const auto [stream_id, sensor_id] = streams[wanted];
    const auto sensor = sensors.find(sensor_id);
    if (sensor == sensors.end() || sensor->second.empty()) {
      fail(fmt::format("its lidar stream {} names sensor entry {}, which holds no LidarSensor metadata", stream_id,
                       sensor_id));
    }
    info.lidar_stream_id = stream_id;
    info.sensor_metadata = sensor->second;
  }

  // Advances to the next chunk block; false after the last.
  bool next_chunk_block() {
    if (next_chunk >= chunks_end) return false;
    const uint64_t offset = next_chunk;
    chunk = read_block(offset, chunks_end, "a chunk");
    chunk_table = verified_root<ChunkTable>(chunk.data(), chunk.size() - kCrcBytes, "OSF!");
    if (!chunk_table) fail(fmt::format("the chunk at byte {} is not a valid OSF chunk flatbuffer", offset));
    next_chunk += chunk.size();
    next_message = 0;
    return true;
  }

  OsfScan scan_of(const StampedMessageTable& message);
};

OsfScan OsfReader::Impl::scan_of(const StampedMessageTable& message) {
  const fb::Vector<uint8_t>* buffer = message.buffer();
  try {
    return decode_scan_message(
        buffer ? std::span<const uint8_t>(buffer->data(), buffer->size()) : std::span<const uint8_t>(),
        message.receive_ns());
  } catch (const MessageError& e) {
    fail(fmt::format("scan {}, {}", scans, e.what()));
  }
}

OsfReader::OsfReader(const fs::path& path, size_t lidar_stream) : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.path = path;
  d.wanted = lidar_stream;
  std::error_code ec;
  d.file_size = fs::file_size(path, ec);
  if (ec || !fs::is_regular_file(path)) d.fail("no such OSF file");
  d.in.open(path, std::ios::binary);
  if (!d.in) d.fail("cannot open it");
  if (!is_osf_file(path)) d.fail("not an OSF file (it does not start with an OSF header, identifier \"OSF$\")");
  d.read_header();
}

OsfReader::~OsfReader() = default;

const OsfFileInfo& OsfReader::info() const { return impl_->info; }

std::optional<OsfScan> OsfReader::next() {
  Impl& d = *impl_;
  for (;;) {
    const auto* messages = d.chunk_table ? d.chunk_table->messages() : nullptr;
    while (messages && d.next_message < messages->size()) {
      const StampedMessageTable* message = messages->Get(static_cast<fb::uoffset_t>(d.next_message++));
      if (message->stream_id() != d.info.lidar_stream_id) continue;
      OsfScan scan = d.scan_of(*message);
      ++d.scans;
      return scan;
    }
    if (!d.next_chunk_block()) return std::nullopt;
  }
}

}  // namespace lidartwin
