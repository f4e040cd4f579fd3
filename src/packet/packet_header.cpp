// PacketHeader members by table field (the header tables in field_table.cpp name fields, not members).
#include "lidartwin/packet/scan.h"
#include "packet/packet_format_impl.h"

namespace lidartwin::packet_detail {

uint64_t header_value(const PacketHeader& header, HeaderField field) {
  switch (field) {
    case HeaderField::kPacketType: return header.packet_type;
    case HeaderField::kFrameId: return header.frame_id;
    case HeaderField::kInitId: return header.init_id;
    case HeaderField::kProdSn: return header.prod_sn;
    case HeaderField::kAlertFlags: return header.alert_flags;
    case HeaderField::kCountdownThermalShutdown: return header.countdown_thermal_shutdown;
    case HeaderField::kCountdownShotLimiting: return header.countdown_shot_limiting;
    case HeaderField::kThermalShutdown: return header.thermal_shutdown;
    case HeaderField::kShotLimiting: return header.shot_limiting;
  }
  return 0;
}

// Values come from codecs no wider than the member, so the narrowing casts keep every bit.
void set_header_value(PacketHeader& header, HeaderField field, uint64_t value) {
  switch (field) {
    case HeaderField::kPacketType: header.packet_type = static_cast<uint16_t>(value); break;
    case HeaderField::kFrameId: header.frame_id = static_cast<uint32_t>(value); break;
    case HeaderField::kInitId: header.init_id = static_cast<uint32_t>(value); break;
    case HeaderField::kProdSn: header.prod_sn = value; break;
    case HeaderField::kAlertFlags: header.alert_flags = static_cast<uint8_t>(value); break;
    case HeaderField::kCountdownThermalShutdown: header.countdown_thermal_shutdown = static_cast<uint8_t>(value); break;
    case HeaderField::kCountdownShotLimiting: header.countdown_shot_limiting = static_cast<uint8_t>(value); break;
    case HeaderField::kThermalShutdown: header.thermal_shutdown = static_cast<uint8_t>(value); break;
    case HeaderField::kShotLimiting: header.shot_limiting = static_cast<uint8_t>(value); break;
  }
}

}  // namespace lidartwin::packet_detail
