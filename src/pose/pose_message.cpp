// The live pose message's wire form (include/lidartwin/pose/pose_message.h).
#include "lidartwin/pose/pose_message.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace lidartwin {
namespace {
static_assert(std::endian::native == std::endian::little, "the pose message is little-endian on the wire");

template <typename T>
T read_at(std::span<const uint8_t> bytes, size_t offset) {
  T value;
  std::memcpy(&value, bytes.data() + offset, sizeof value);
  return value;
}

template <typename T>
void write_at(std::span<uint8_t> bytes, size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof value);
}

Eigen::Vector3d read_vector(std::span<const uint8_t> bytes, size_t offset) {
  return {read_at<double>(bytes, offset), read_at<double>(bytes, offset + 8), read_at<double>(bytes, offset + 16)};
}

void write_vector(std::span<uint8_t> bytes, size_t offset, const Eigen::Vector3d& v) {
  for (int i = 0; i < 3; ++i) write_at(bytes, offset + 8 * static_cast<size_t>(i), v[i]);
}

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }
}  // namespace

const char* to_string(PoseRejection reason) {
  switch (reason) {
    case PoseRejection::kSize: return "size";
    case PoseRejection::kMagic: return "magic";
    case PoseRejection::kVersion: return "version";
    case PoseRejection::kFlags: return "flags";
    case PoseRejection::kMalformed: return "malformed";
    case PoseRejection::kNotFinite: return "not_finite";
    case PoseRejection::kQuaternion: return "quaternion";
    case PoseRejection::kTimeBackwards: return "time_backwards";
    case PoseRejection::kCount: break;
  }
  return "unknown";
}

void validate_pose_message(PoseMessage& message, const Eigen::Vector4d& q, const std::string& where) {
  if (!finite(message.pose.translation) || !q.allFinite() || (message.velocity && !finite(*message.velocity)) ||
      (message.angular_rate && !finite(*message.angular_rate))) {
    throw PoseRejected(PoseRejection::kNotFinite, where +
                                                      ": position, orientation, velocity and angular rate "
                                                      "must be finite numbers (got NaN or infinity)");
  }
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    throw PoseRejected(
        PoseRejection::kQuaternion,
        where + ": orientation qx qy qz qw must be a unit quaternion, its norm is " + std::to_string(norm));
  }
  message.pose.rotation = Eigen::Quaterniond(q[3] / norm, q[0] / norm, q[1] / norm, q[2] / norm);
}

PoseMessage decode_pose_message(std::span<const uint8_t> bytes) {
  if (bytes.size() != kPoseMessageSize) {
    throw PoseRejected(PoseRejection::kSize, "pose message of " + std::to_string(bytes.size()) +
                                                 " bytes: must be exactly " + std::to_string(kPoseMessageSize));
  }
  if (std::memcmp(bytes.data(), kPoseMessageMagic.data(), kPoseMessageMagic.size()) != 0) {
    throw PoseRejected(PoseRejection::kMagic, "pose message: must start with \"LTPS\" (not a lidartwin pose message)");
  }
  const auto version = read_at<uint16_t>(bytes, 4);
  if (version != kPoseMessageVersion) {
    throw PoseRejected(PoseRejection::kVersion, "pose message version " + std::to_string(version) +
                                                    ": this lidartwin reads version " +
                                                    std::to_string(kPoseMessageVersion));
  }
  PoseMessage message;
  message.sequence = read_at<uint32_t>(bytes, 8);
  const std::string where = "pose message " + std::to_string(message.sequence);
  const auto flags = read_at<uint16_t>(bytes, 6);
  if ((flags & ~(kPoseHasVelocity | kPoseHasAngularRate)) != 0 || read_at<uint32_t>(bytes, 12) != 0) {
    throw PoseRejected(PoseRejection::kFlags,
                       where + ": unknown flag bits or a non-zero reserved field (version 1 defines flag bits 0-1)");
  }
  message.time_ns = read_at<int64_t>(bytes, 16);
  message.pose.translation = read_vector(bytes, 24);
  const Eigen::Vector4d q(read_at<double>(bytes, 48), read_at<double>(bytes, 56), read_at<double>(bytes, 64),
                          read_at<double>(bytes, 72));
  if (flags & kPoseHasVelocity) message.velocity = read_vector(bytes, 80);
  if (flags & kPoseHasAngularRate) message.angular_rate = read_vector(bytes, 104);
  validate_pose_message(message, q, where);
  return message;
}

std::array<uint8_t, kPoseMessageSize> encode_pose_message(const PoseMessage& message) {
  std::array<uint8_t, kPoseMessageSize> bytes{};
  std::memcpy(bytes.data(), kPoseMessageMagic.data(), kPoseMessageMagic.size());
  write_at<uint16_t>(bytes, 4, kPoseMessageVersion);
  const auto flags = static_cast<uint16_t>((message.velocity ? kPoseHasVelocity : 0) |
                                           (message.angular_rate ? kPoseHasAngularRate : 0));
  write_at<uint16_t>(bytes, 6, flags);
  write_at<uint32_t>(bytes, 8, message.sequence);
  write_at<int64_t>(bytes, 16, message.time_ns);
  write_vector(bytes, 24, message.pose.translation);
  const Eigen::Quaterniond& q = message.pose.rotation;
  write_at(bytes, 48, q.x());
  write_at(bytes, 56, q.y());
  write_at(bytes, 64, q.z());
  write_at(bytes, 72, q.w());
  if (message.velocity) write_vector(bytes, 80, *message.velocity);
  if (message.angular_rate) write_vector(bytes, 104, *message.angular_rate);
  return bytes;
}

}  // namespace lidartwin
