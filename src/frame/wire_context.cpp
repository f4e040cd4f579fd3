#include "lidartwin/frame/wire_context.h"

#include <algorithm>

namespace lidartwin {

ColumnContext wire_context(const PacketFormat& packets, float signal_gain) {
  ColumnContext context;
  context.range_step_m = static_cast<float>(packets.channel_step(ChannelField::kRange)) / 1000.0f;
  context.max_wire_range_m = static_cast<float>(packets.channel_max(ChannelField::kRange)) / 1000.0f;
  context.signal_gain = signal_gain;
  const auto wire_max = [&](ChannelField f) {
    return packets.has_channel(f) ? static_cast<float>(packets.channel_max(f)) : 0.0f;
  };
  context.max_wire_signal = wire_max(ChannelField::kSignal);
  context.max_wire_near_ir = wire_max(ChannelField::kNearIr);
  if (packets.has_channel(ChannelField::kNearIr)) {
    context.near_ir_step = static_cast<float>(packets.channel_step(ChannelField::kNearIr));
  }
  context.columns_per_frame = static_cast<uint32_t>(packets.format().columns_per_frame);
  return context;
}

float cast_reach_m(double max_range_m, const PacketFormat& packets) {
  const double wire_m = packets.channel_max(ChannelField::kRange) / 1000.0;
  return static_cast<float>(std::min(max_range_m + 1.0, wire_m));
}

}  // namespace lidartwin
