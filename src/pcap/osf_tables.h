#pragma once
// The flatbuffer tables of an OSF file that lidartwin reads, as views over the low-level flatbuffers
// API: each accessor reads one field by its vtable slot, each Verify checks what the accessors touch
// so a hostile file fails verification instead of reading out of bounds.
//
// Field ids are the declaration order of the tables in ouster-sdk 1.0.1 (commit 46b7bce),
// ouster_osf/fb/*.fbs, namespace ouster.sdk.osf.v2; a field's vtable slot is 4 + 2 * id. Fields
// appended by newer schema minor versions come after these and are simply not read.
#include <cstddef>
#include <cstdint>

#include <flatbuffers/flatbuffers.h>

namespace lidartwin::osf_detail {

namespace fb = flatbuffers;

constexpr fb::voffset_t slot(int id) { return static_cast<fb::voffset_t>(4 + 2 * id); }

// header.fbs, identifier "OSF$": version 0, status 1, metadata_offset 2, file_length 3.
struct HeaderTable : private fb::Table {
  uint64_t version() const { return GetField<uint64_t>(slot(0), 0); }
  uint8_t status() const { return GetField<uint8_t>(slot(1), 0); }  // 2: VALID (finished writing)
  uint64_t metadata_offset() const { return GetField<uint64_t>(slot(2), 1); }
  uint64_t file_length() const { return GetField<uint64_t>(slot(3), 1); }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyField<uint64_t>(v, slot(0), 8) && VerifyField<uint8_t>(v, slot(1), 1) &&
           VerifyField<uint64_t>(v, slot(2), 8) && VerifyField<uint64_t>(v, slot(3), 8) && v.EndTable();
  }
};

// metadata.fbs MetadataEntry: id 0, type 1 (e.g. "ouster/v1/os_sensor/LidarSensor"), buffer 2 (a
// size-prefixed flatbuffer of that type).
struct MetadataEntryTable : private fb::Table {
  uint32_t id() const { return GetField<uint32_t>(slot(0), 0); }
  const fb::String* type() const { return GetPointer<const fb::String*>(slot(1)); }
  const fb::Vector<uint8_t>* buffer() const { return GetPointer<const fb::Vector<uint8_t>*>(slot(2)); }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyField<uint32_t>(v, slot(0), 4) && VerifyOffset(v, slot(1)) &&
           v.VerifyString(type()) && VerifyOffset(v, slot(2)) && v.VerifyVector(buffer()) && v.EndTable();
  }
};

// metadata.fbs Metadata, identifier "OSF#": id 0 (the writer, "ouster_sdk"), start_ts 1, end_ts 2,
// chunks 3, entries 4.
struct MetadataTable : private fb::Table {
  const fb::String* writer() const { return GetPointer<const fb::String*>(slot(0)); }
  uint64_t start_ns() const { return GetField<uint64_t>(slot(1), 0); }
  uint64_t end_ns() const { return GetField<uint64_t>(slot(2), 0); }
  const fb::Vector<fb::Offset<MetadataEntryTable>>* entries() const {
    return GetPointer<const fb::Vector<fb::Offset<MetadataEntryTable>>*>(slot(4));
  }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyOffset(v, slot(0)) && v.VerifyString(writer()) &&
           VerifyField<uint64_t>(v, slot(1), 8) && VerifyField<uint64_t>(v, slot(2), 8) && VerifyOffset(v, slot(4)) &&
           v.VerifyVector(entries()) && v.VerifyVectorOfTables(entries()) && v.EndTable();
  }
};

// os_sensor/lidar_sensor.fbs LidarSensor, identifier "oLS_": metadata 0 (the sensor's metadata JSON).
struct LidarSensorTable : private fb::Table {
  const fb::String* metadata() const { return GetPointer<const fb::String*>(slot(0)); }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyOffset(v, slot(0)) && v.VerifyString(metadata()) && v.EndTable();
  }
};

// os_sensor/lidar_scan_stream.fbs LidarScanStream (declares identifier "oLSS", but files carry none): sensor_id 0 (the
// id of the LidarSensor entry whose scans it holds).
struct LidarScanStreamTable : private fb::Table {
  uint32_t sensor_id() const { return GetField<uint32_t>(slot(0), 0); }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyField<uint32_t>(v, slot(0), 4) && v.EndTable();
  }
};

// chunk.fbs StampedMessage: ts 0 (receive time, ns), id 1 (the stream's metadata entry id),
// buffer 2 (a size-prefixed flatbuffer of the stream's message type).
struct StampedMessageTable : private fb::Table {
  uint64_t receive_ns() const { return GetField<uint64_t>(slot(0), 0); }
  uint32_t stream_id() const { return GetField<uint32_t>(slot(1), 0); }
  const fb::Vector<uint8_t>* buffer() const { return GetPointer<const fb::Vector<uint8_t>*>(slot(2)); }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyField<uint64_t>(v, slot(0), 8) && VerifyField<uint32_t>(v, slot(1), 4) &&
           VerifyOffset(v, slot(2)) && v.VerifyVector(buffer()) && v.EndTable();
  }
};

// chunk.fbs Chunk, identifier "OSF!": messages 0.
struct ChunkTable : private fb::Table {
  const fb::Vector<fb::Offset<StampedMessageTable>>* messages() const {
    return GetPointer<const fb::Vector<fb::Offset<StampedMessageTable>>*>(slot(0));
  }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyOffset(v, slot(0)) && v.VerifyVector(messages()) &&
           v.VerifyVectorOfTables(messages()) && v.EndTable();
  }
};

// lidar_scan_stream.fbs ChannelData: buffer 0 (one field's image, encoded: PNG or ZPNG).
struct ChannelDataTable : private fb::Table {
  const fb::Vector<uint8_t>* buffer() const { return GetPointer<const fb::Vector<uint8_t>*>(slot(0)); }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyOffset(v, slot(0)) && v.VerifyVector(buffer()) && v.EndTable();
  }
};

// lidar_scan_stream.fbs struct ChannelField: { chan_field: uint8 (CHAN_FIELD), chan_field_type:
// uint8 (CHAN_FIELD_TYPE) }, two bytes.
struct ChannelFieldStruct {
  uint8_t field;
  uint8_t type;
};
static_assert(sizeof(ChannelFieldStruct) == 2);

// lidar_scan_stream.fbs LidarScanMsg: channels 0 (one per field_types entry, same order),
// field_types 1, header_timestamp 2 (per column, ns), header_measurement_id 3, header_status 4,
// frame_id 5, packet_timestamp 7 (per packet, ns; 0 where none arrived).
struct LidarScanMsgTable : private fb::Table {
  const fb::Vector<fb::Offset<ChannelDataTable>>* channels() const {
    return GetPointer<const fb::Vector<fb::Offset<ChannelDataTable>>*>(slot(0));
  }
  const fb::Vector<const ChannelFieldStruct*>* field_types() const {
    return GetPointer<const fb::Vector<const ChannelFieldStruct*>*>(slot(1));
  }
  const fb::Vector<uint64_t>* column_timestamps() const { return GetPointer<const fb::Vector<uint64_t>*>(slot(2)); }
  const fb::Vector<uint16_t>* measurement_ids() const { return GetPointer<const fb::Vector<uint16_t>*>(slot(3)); }
  const fb::Vector<uint32_t>* column_status() const { return GetPointer<const fb::Vector<uint32_t>*>(slot(4)); }
  int32_t frame_id() const { return GetField<int32_t>(slot(5), 0); }
  const fb::Vector<uint64_t>* packet_timestamps() const { return GetPointer<const fb::Vector<uint64_t>*>(slot(7)); }
  bool Verify(fb::Verifier& v) const {
    return VerifyTableStart(v) && VerifyOffset(v, slot(0)) && v.VerifyVector(channels()) &&
           v.VerifyVectorOfTables(channels()) && VerifyOffset(v, slot(1)) && v.VerifyVector(field_types()) &&
           VerifyOffset(v, slot(2)) && v.VerifyVector(column_timestamps()) && VerifyOffset(v, slot(3)) &&
           v.VerifyVector(measurement_ids()) && VerifyOffset(v, slot(4)) && v.VerifyVector(column_status()) &&
           VerifyField<int32_t>(v, slot(5), 4) && VerifyOffset(v, slot(7)) && v.VerifyVector(packet_timestamps()) &&
           v.EndTable();
  }
};

// The root table of a size-prefixed flatbuffer, or nullptr if the bytes do not verify as one.
template <typename Table>
const Table* verified_root(const uint8_t* data, size_t size, const char* identifier) {
  fb::Verifier verifier(data, size);
  if (!verifier.VerifySizePrefixedBuffer<Table>(identifier)) return nullptr;
  return fb::GetSizePrefixedRoot<Table>(data);
}

}  // namespace lidartwin::osf_detail
