#include "lidartwin/packet/scan_batcher.h"

namespace lidartwin {

ScanBatcher::ScanBatcher(const LidarDataFormat& format, std::optional<SensorIds> sensor)
    : format_(format),
      expected_(static_cast<size_t>(format_.packets_per_frame())),
      sensor_(sensor),
      frame_id_mask_(uses_fusa_header(format) ? 0xFFFF'FFFFu : 0xFFFFu),
      probe_(format) {}

bool ScanBatcher::late(uint32_t frame_id) const {
  return released_id_ && (frame_id == *released_id_ || ((frame_id + 1) & frame_id_mask_) == *released_id_);
}

std::optional<BatchedFrame> ScanBatcher::add(std::span<const uint8_t> datagram) {
  if (datagram.size() != format_.lidar_packet_size()) {
    ++counts_.wrong_size;
    return std::nullopt;
  }
  std::string error;
  const auto decoded = format_.decode(datagram, probe_, &error);
  if (!decoded) {
    if (counts_.undecodable++ == 0) first_error_ = error;
    return std::nullopt;
  }
  const PacketHeader& header = decoded->header;
  const bool legacy = format_.format().udp_profile_lidar == UdpProfileLidar::kLegacy;
  if (sensor_ && !legacy && (header.init_id != sensor_->init_id || header.prod_sn != sensor_->prod_sn)) {
    ++counts_.foreign;
    return std::nullopt;
  }
  if (late(header.frame_id)) {
    ++counts_.late;
    return std::nullopt;
  }
  std::optional<BatchedFrame> released;
  const bool restart = open_ && !legacy && !open_->init_ids.contains(header.init_id);
  if (open_ && (open_->frame_id != header.frame_id || restart)) released = release();
  if (restart) released_id_.reset();  // a new session may reuse any frame_id (6.2)
  if (!open_) open_ = BatchedFrame{Scan(format_.format()), header.frame_id, 0, false, {}, {}};
  format_.decode(datagram, open_->scan, &error);
  ++open_->packets;
  ++counts_.batched;
  open_->init_ids.insert(header.init_id);
  open_->prod_sns.insert(header.prod_sn);
  last_packet_ = decoded;
  if (open_->packets >= expected_) {
    open_->complete = true;
    return release();
  }
  return released;
}

std::optional<BatchedFrame> ScanBatcher::flush() {
  auto frame = std::move(open_);
  open_.reset();
  released_id_.reset();
  return frame;
}

std::optional<BatchedFrame> ScanBatcher::release() {
  released_id_ = open_->frame_id;
  auto frame = std::move(open_);
  open_.reset();
  return frame;
}

}  // namespace lidartwin
