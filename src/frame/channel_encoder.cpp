#include "frame/channel_encoder.h"

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <vector>

#include "frame/channel_kernels.h"

namespace lidartwin::frame_detail {
namespace {

// range_mm = round(range_m * 1000) to the field's step; 0 means no return, and so does a range
// the field cannot hold (a clamped range would be a false point at the field's end). Values stay
// below 2^20, so the conversion goes through int32 (one instruction, vectorized).
template <std::vector<float> MeasuredColumn::*Member>
void write_range(const ChannelLimits& c, const MeasuredColumn& measured, std::span<uint32_t> out) {
  range_steps((measured.*Member).data(), out.size(), c.scale / c.step, 0.5f, c.max / c.step + 0.5f,
              static_cast<int32_t>(c.step), out.data());
}

// Signal, near-IR and reflectivity saturate at their field's maximum; negative or NaN gives 0.
template <std::vector<float> MeasuredColumn::*Member>
void write_clamped(const ChannelLimits& c, const MeasuredColumn& measured, std::span<uint32_t> out) {
  clamped_steps((measured.*Member).data(), out.size(), 1.0f / c.step, c.max / c.step, static_cast<int32_t>(c.step),
                out.data());
}

struct Source {
  ChannelField field;
  float scale;
  ChannelEncoder::Writer write;
};
// Which MeasuredColumn array feeds which channel. FLAGS and WINDOW are opaque to the SDK: left 0 (4.6).
constexpr Source kSources[] = {
    {ChannelField::kRange, 1000.0f, &write_range<&MeasuredColumn::range_m>},
    {ChannelField::kReflectivity, 1.0f, &write_clamped<&MeasuredColumn::reflectivity>},
    {ChannelField::kSignal, 1.0f, &write_clamped<&MeasuredColumn::signal_photons>},
    {ChannelField::kNearIr, 1.0f, &write_clamped<&MeasuredColumn::near_ir_photons>},
    {ChannelField::kRange2, 1000.0f, &write_range<&MeasuredColumn::range2_m>},
    {ChannelField::kReflectivity2, 1.0f, &write_clamped<&MeasuredColumn::reflectivity2>},
    {ChannelField::kSignal2, 1.0f, &write_clamped<&MeasuredColumn::signal2_photons>},
};

}  // namespace

ChannelEncoder::ChannelEncoder(const PacketFormat& format) {
  for (const Source& source : kSources) {
    if (!format.has_channel(source.field)) continue;
    const ChannelLimits limits{source.scale, static_cast<float>(format.channel_step(source.field)),
                               static_cast<float>(format.channel_max(source.field))};
    channels_.push_back({source.field, limits, source.write});
  }
  for (int f = 0; f < kChannelFieldCount; ++f) {
    if (format.has_channel(static_cast<ChannelField>(f))) fields_.push_back(static_cast<ChannelField>(f));
  }
}

void ChannelEncoder::write(const MeasuredColumn& measured, int column, Scan& scan) const {
  assert(static_cast<int>(measured.size()) == scan.height);
  for (const Channel& channel : channels_) channel.write(channel.limits, measured, scan.column(channel.field, column));
}

void ChannelEncoder::clear(int column, Scan& scan) const {
  for (const ChannelField field : fields_) std::ranges::fill(scan.column(field, column), 0u);
}

}  // namespace lidartwin::frame_detail
