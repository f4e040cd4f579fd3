#pragma once
// The live pose message a HIL rig sends: one UDP datagram of 128 bytes (or the same fields as JSON
// over HTTP, rig/pose_api). docs/live-poses.md is the reference; this is its one decoder.
//
//   offset  type      field
//   0       char[4]   magic "LTPS"
//   4       u16       version (1)
//   6       u16       flags: bit 0 velocity valid, bit 1 angular rate valid, others 0
//   8       u32       sequence (counts up by one per message; gaps are counted as lost)
//   12      u32       reserved, 0
//   16      i64       time_ns on the sender's clock (PoseClock says which)
//   24      f64 x3    position x y z (m), world frame (Z up)
//   48      f64 x4    orientation qx qy qz qw (unit), world_from_vehicle
//   80      f64 x3    velocity (m/s), world frame
//   104     f64 x3    angular rate (rad/s), vehicle frame
// All little-endian.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/pose/pose.h"

namespace lidartwin {

inline constexpr size_t kPoseMessageSize = 128;
inline constexpr std::array<char, 4> kPoseMessageMagic{'L', 'T', 'P', 'S'};
inline constexpr uint16_t kPoseMessageVersion = 1;
inline constexpr uint16_t kPoseHasVelocity = 1;
inline constexpr uint16_t kPoseHasAngularRate = 2;
// How far from unit length a quaternion may be (a sender's float rounding) before it is refused.
inline constexpr double kQuaternionNormTolerance = 1e-3;

struct PoseMessage {
  uint32_t sequence = 0;
  int64_t time_ns = 0;                          // on the sender's clock
  Pose pose;                                    // world_from_vehicle, rotation normalized
  std::optional<Eigen::Vector3d> velocity;      // m/s, world frame
  std::optional<Eigen::Vector3d> angular_rate;  // rad/s, vehicle frame
};

// Why a message was refused; each is counted on its own (LivePoseStats).
enum class PoseRejection {
  kSize,           // a datagram not of kPoseMessageSize bytes
  kMagic,          // not a pose message
  kVersion,        // a version this lidartwin does not read
  kFlags,          // unknown flag bits or a non-zero reserved field
  kMalformed,      // an HTTP body that is not the JSON form (bad JSON, a missing or mistyped field)
  kNotFinite,      // NaN or infinity anywhere
  kQuaternion,     // orientation not a unit quaternion
  kTimeBackwards,  // not after the newest accepted pose (late, repeated or out of order)
  kCount
};
const char* to_string(PoseRejection reason);  // "size", "magic", ... (the stats keys)

class PoseRejected : public InputError {
 public:
  PoseRejected(PoseRejection reason, const std::string& message) : InputError(message), reason_(reason) {}
  PoseRejection reason() const { return reason_; }

 private:
  PoseRejection reason_;
};

// Throws PoseRejected naming the field and the problem.
PoseMessage decode_pose_message(std::span<const uint8_t> bytes);
// Checks what both wire forms share (finite values, a unit quaternion) and normalizes the rotation;
// throws PoseRejected. `where` prefixes messages ("pose message 17").
void validate_pose_message(PoseMessage& message, const Eigen::Vector4d& quaternion_xyzw, const std::string& where);
std::array<uint8_t, kPoseMessageSize> encode_pose_message(const PoseMessage& message);

}  // namespace lidartwin
