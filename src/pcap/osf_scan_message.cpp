#include "pcap/osf_scan_message.h"

#include <string>
#include <vector>

#include <fmt/format.h>

#include "pcap/osf_image.h"
#include "pcap/osf_tables.h"

namespace lidartwin::osf_detail {
namespace {

// The per-pixel fields of OsfField (CHAN_FIELD 1-9); custom fields and raw words are not read.
bool read_field(uint8_t field) { return field >= 1 && field <= 9; }

template <typename T>
std::vector<T> copy_of(const fb::Vector<T>* v) {
  return v ? std::vector<T>(v->begin(), v->end()) : std::vector<T>();
}

void read_columns(const LidarScanMsgTable& msg, OsfScan& scan) {
  scan.frame_id = msg.frame_id();
  scan.column_timestamp_ns = copy_of(msg.column_timestamps());
  scan.measurement_id = copy_of(msg.measurement_ids());
  scan.column_status = copy_of(msg.column_status());
  scan.packet_timestamp_ns = copy_of(msg.packet_timestamps());
  const size_t width = scan.column_timestamp_ns.size();
  if (width == 0) throw MessageError("no column timestamps");
  if (scan.measurement_id.size() != width || scan.column_status.size() != width) {
    throw MessageError(fmt::format("{} column timestamps but {} measurement ids and {} column statuses", width,
                                   scan.measurement_id.size(), scan.column_status.size()));
  }
  scan.width = static_cast<int>(width);
}

OsfImage read_image(const ChannelDataTable& channel, OsfField field, const OsfScan& scan) {
  const fb::Vector<uint8_t>* encoded = channel.buffer();
  FieldImage image;
  try {
    image = decode_field_image(encoded ? std::span<const uint8_t>(encoded->data(), encoded->size())
                                       : std::span<const uint8_t>());
  } catch (const ImageError& e) {
    throw MessageError(fmt::format("field {}: {}", to_string(field), e.what()));
  }
  if (image.width != scan.width || (scan.height != 0 && image.height != scan.height)) {
    throw MessageError(fmt::format("field {}: a {}x{} image in a scan of {} columns{}", to_string(field), image.width,
                                   image.height, scan.width,
                                   scan.height ? fmt::format(" and {} rows", scan.height) : ""));
  }
  return {field, std::move(image.values), image.destaggered};
}

}  // namespace

OsfScan decode_scan_message(std::span<const uint8_t> message, uint64_t receive_ns) {
  const auto* msg = verified_root<LidarScanMsgTable>(message.data(), message.size(), nullptr);
  if (!msg) throw MessageError("not a valid LidarScan message");
  OsfScan scan;
  scan.receive_ns = receive_ns;
  read_columns(*msg, scan);
  const auto* types = msg->field_types();
  const auto* channels = msg->channels();
  const size_t fields = types ? types->size() : 0;
  if (fields == 0 || !channels || channels->size() != fields) {
    throw MessageError(fmt::format("{} field types but {} channels", fields, channels ? channels->size() : 0));
  }
  for (fb::uoffset_t i = 0; i < fields; ++i) {
    const ChannelFieldStruct* type = types->Get(i);
    if (!read_field(type->field)) continue;
    const auto field = static_cast<OsfField>(type->field);
    if (type->type < 1 || type->type > 3) {  // CHAN_FIELD_TYPE UINT8, UINT16, UINT32
      throw MessageError(fmt::format("field {} has storage type {}, not an unsigned 8-, 16- or 32-bit integer",
                                     to_string(field), type->type));
    }
    scan.images.push_back(read_image(*channels->Get(i), field, scan));
    scan.height = static_cast<int>(scan.images.back().values.size() / static_cast<size_t>(scan.width));
  }
  return scan;
}

}  // namespace lidartwin::osf_detail
