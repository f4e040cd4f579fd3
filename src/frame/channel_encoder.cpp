#include "frame/channel_encoder.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cstdint>
#include <iterator>
#include <vector>

namespace lidartwin::frame_detail {
namespace {

// Which MeasuredColumn array feeds which channel, and how (m -> mm for ranges). FLAGS and WINDOW
// are opaque to the SDK: left 0 (4.6).
struct Source {
  ChannelField field;
  std::vector<float> MeasuredColumn::*values;
  bool range;
};
constexpr Source kSources[] = {
    {ChannelField::kRange, &MeasuredColumn::range_m, true},
    {ChannelField::kReflectivity, &MeasuredColumn::reflectivity, false},
    {ChannelField::kSignal, &MeasuredColumn::signal_photons, false},
    {ChannelField::kNearIr, &MeasuredColumn::near_ir_photons, false},
    {ChannelField::kRange2, &MeasuredColumn::range2_m, true},
    {ChannelField::kReflectivity2, &MeasuredColumn::reflectivity2, false},
    {ChannelField::kSignal2, &MeasuredColumn::signal2_photons, false},
};

// range_mm = round(range_m * 1000) to the field's step; 0 means no return, and so does a range
// the field cannot hold (a clamped range would be a false point at the field's end). Values stay
// below 2^20, so the conversion goes through int32 (one instruction, vectorized). Signal, near-IR
// and reflectivity saturate at their field's maximum; negative or NaN gives 0.
ChannelConversion conversion(const Source& source, float step, float max) {
  if (source.range)
    return {nullptr, nullptr, true, 1000.0f / step, 0.5f, max / step + 0.5f, static_cast<int32_t>(step)};
  return {nullptr, nullptr, false, 1.0f / step, 0.0f, max / step, static_cast<int32_t>(step)};
}

}  // namespace

ChannelEncoder::ChannelEncoder(const PacketFormat& format) {
  for (const Source& source : kSources) {
    if (!format.has_channel(source.field)) continue;
    channels_.push_back({source.field, source.values,
                         conversion(source, static_cast<float>(format.channel_step(source.field)),
                                    static_cast<float>(format.channel_max(source.field)))});
  }
  for (int f = 0; f < kChannelFieldCount; ++f) {
    if (format.has_channel(static_cast<ChannelField>(f))) fields_.push_back(static_cast<ChannelField>(f));
  }
}

void ChannelEncoder::write(const MeasuredColumn& measured, int column, Scan& scan) const {
  assert(static_cast<int>(measured.size()) == scan.height);
  std::array<ChannelConversion, std::size(kSources)> conversions;
  for (size_t k = 0; k < channels_.size(); ++k) {
    conversions[k] = channels_[k].conversion;
    conversions[k].values = (measured.*channels_[k].values).data();
    conversions[k].out = scan.column(channels_[k].field, column).data();
  }
  convert_channels(conversions.data(), channels_.size(), measured.size());
}

void ChannelEncoder::clear(int column, Scan& scan) const {
  for (const ChannelField field : fields_) std::ranges::fill(scan.column(field, column), 0u);
}

}  // namespace lidartwin::frame_detail
