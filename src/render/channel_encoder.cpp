#include "render/channel_encoder.h"

#include <algorithm>
#include <cassert>

namespace lidartwin::render_detail {
namespace {

struct Source {
  ChannelField field;
  float Measurement::*value;
  bool is_range;
};
// Which Measurement member feeds which channel. FLAGS and WINDOW are opaque to the SDK: left 0 (4.6).
constexpr Source kSources[] = {
    {ChannelField::kRange, &Measurement::range_m, true},
    {ChannelField::kReflectivity, &Measurement::reflectivity, false},
    {ChannelField::kSignal, &Measurement::signal_photons, false},
    {ChannelField::kNearIr, &Measurement::near_ir_photons, false},
    {ChannelField::kRange2, &Measurement::range2_m, true},
    {ChannelField::kReflectivity2, &Measurement::reflectivity2, false},
    {ChannelField::kSignal2, &Measurement::signal2_photons, false},
};

}  // namespace

ChannelEncoder::ChannelEncoder(const PacketFormat& format) {
  for (const Source& source : kSources) {
    if (!format.has_channel(source.field)) continue;
    channels_.push_back({source.field, source.value, source.is_range ? 1000.0f : 1.0f,
                         static_cast<float>(format.channel_step(source.field)),
                         static_cast<float>(format.channel_max(source.field)), source.is_range});
  }
  for (int f = 0; f < kChannelFieldCount; ++f) {
    if (format.has_channel(static_cast<ChannelField>(f))) fields_.push_back(static_cast<ChannelField>(f));
  }
}

// range_mm = round(range_m * 1000) to the field's step; 0 means no return, and so does a range
// the field cannot hold (a clamped range would be a false point at the field's end).
void ChannelEncoder::write_range(const Channel& c, std::span<const Measurement> measured, std::span<uint32_t> out) {
  const float inv_step = 1.0f / c.step;
  const float lowest = 0.5f * c.step;
  const float limit = c.max + 0.5f * c.step;
  for (size_t r = 0; r < out.size(); ++r) {
    const float v = measured[r].*c.value * c.scale;
    const bool representable = v >= lowest && v < limit;
    out[r] = representable ? static_cast<uint32_t>(v * inv_step + 0.5f) * static_cast<uint32_t>(c.step) : 0u;
  }
}

void ChannelEncoder::write_clamped(const Channel& c, std::span<const Measurement> measured, std::span<uint32_t> out) {
  const float inv_step = 1.0f / c.step;
  for (size_t r = 0; r < out.size(); ++r) {
    const float v = std::clamp(measured[r].*c.value * c.scale, 0.0f, c.max);  // NaN stays NaN: next line
    out[r] = v >= 0.0f ? static_cast<uint32_t>(v * inv_step + 0.5f) * static_cast<uint32_t>(c.step) : 0u;
  }
}

void ChannelEncoder::write(std::span<const Measurement> measured, int column, Scan& scan) const {
  assert(static_cast<int>(measured.size()) == scan.height);
  for (const Channel& channel : channels_) {
    const std::span<uint32_t> out = scan.column(channel.field, column);
    if (channel.is_range) {
      write_range(channel, measured, out);
    } else {
      write_clamped(channel, measured, out);
    }
  }
}

void ChannelEncoder::clear(int column, Scan& scan) const {
  for (const ChannelField field : fields_) std::ranges::fill(scan.column(field, column), 0u);
}

}  // namespace lidartwin::render_detail
