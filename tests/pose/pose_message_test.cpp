// The live pose message's wire form, checked against bytes laid out by hand from the table in
// docs/live-poses.md (not by the encoder under test), and every way a message is refused.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/pose/pose_message.h"

namespace lidartwin {
namespace {

template <typename T>
void put(std::vector<uint8_t>& bytes, size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof value);
}

// The documented layout: "LTPS", version 1, flags, sequence, reserved, time_ns, position,
// orientation (x y z w), velocity, angular rate.
std::vector<uint8_t> message_bytes(uint32_t sequence, int64_t time_ns, const std::array<double, 3>& p,
                                   const std::array<double, 4>& q, uint16_t flags = 0) {
  std::vector<uint8_t> bytes(128, 0);
  std::memcpy(bytes.data(), "LTPS", 4);
  put<uint16_t>(bytes, 4, 1);
  put<uint16_t>(bytes, 6, flags);
  put<uint32_t>(bytes, 8, sequence);
  put<int64_t>(bytes, 16, time_ns);
  for (size_t i = 0; i < 3; ++i) put<double>(bytes, 24 + 8 * i, p[i]);
  for (size_t i = 0; i < 4; ++i) put<double>(bytes, 48 + 8 * i, q[i]);
  return bytes;
}

PoseRejection rejection_of(const std::vector<uint8_t>& bytes) {
  try {
    decode_pose_message(bytes);
  } catch (const PoseRejected& e) {
    return e.reason();
  }
  ADD_FAILURE() << "the message was accepted";
  return PoseRejection::kCount;
}

TEST(PoseMessage, DecodesTheDocumentedLayout) {
  const double s = std::sqrt(0.5);
  auto bytes = message_bytes(42, 1'234'567'890'123, {1.5, -2.0, 3.25}, {0.0, 0.0, s, s}, 3);
  for (size_t i = 0; i < 3; ++i) put<double>(bytes, 80 + 8 * i, 0.5 * static_cast<double>(i + 1));
  for (size_t i = 0; i < 3; ++i) put<double>(bytes, 104 + 8 * i, -0.1 * static_cast<double>(i + 1));
  const PoseMessage m = decode_pose_message(bytes);
  EXPECT_EQ(m.sequence, 42u);
  EXPECT_EQ(m.time_ns, 1'234'567'890'123);
  EXPECT_EQ(m.pose.translation, Eigen::Vector3d(1.5, -2.0, 3.25));
  // 90 degrees about Z: the vehicle's x axis points along the world's y.
  EXPECT_NEAR((m.pose.rotation * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-12);
  ASSERT_TRUE(m.velocity && m.angular_rate);
  EXPECT_EQ(*m.velocity, Eigen::Vector3d(0.5, 1.0, 1.5));
  EXPECT_EQ(*m.angular_rate, Eigen::Vector3d(-0.1, -0.2, -0.30000000000000004));
  const auto encoded = encode_pose_message(m);  // the encoder writes the same layout back
  EXPECT_TRUE(std::equal(encoded.begin(), encoded.begin() + 48, bytes.begin()));
  EXPECT_TRUE(std::equal(encoded.begin() + 80, encoded.end(), bytes.begin() + 80));
  EXPECT_TRUE(decode_pose_message(encoded).pose.rotation.isApprox(m.pose.rotation, 1e-15));
}

TEST(PoseMessage, OptionalFieldsFollowTheFlags) {
  auto bytes = message_bytes(1, 10, {0, 0, 0}, {0, 0, 0, 1}, 0);
  put<double>(bytes, 80, 99.0);  // present in the bytes, but the flag says it is not valid
  const PoseMessage m = decode_pose_message(bytes);
  EXPECT_FALSE(m.velocity);
  EXPECT_FALSE(m.angular_rate);
}

TEST(PoseMessage, RefusesEachKindOfBadMessageNamingIt) {
  const auto good = message_bytes(7, 100, {1, 2, 3}, {0, 0, 0, 1});
  auto shorter = good;
  shorter.pop_back();
  EXPECT_EQ(rejection_of(shorter), PoseRejection::kSize);
  auto magic = good;
  magic[0] = 'X';
  EXPECT_EQ(rejection_of(magic), PoseRejection::kMagic);
  auto version = good;
  put<uint16_t>(version, 4, 2);
  EXPECT_EQ(rejection_of(version), PoseRejection::kVersion);
  auto flags = good;
  put<uint16_t>(flags, 6, 4);
  EXPECT_EQ(rejection_of(flags), PoseRejection::kFlags);
  auto nan = message_bytes(7, 100, {1, std::numeric_limits<double>::quiet_NaN(), 3}, {0, 0, 0, 1});
  EXPECT_EQ(rejection_of(nan), PoseRejection::kNotFinite);
  auto velocity_inf = message_bytes(7, 100, {1, 2, 3}, {0, 0, 0, 1}, 1);
  put<double>(velocity_inf, 88, std::numeric_limits<double>::infinity());
  EXPECT_EQ(rejection_of(velocity_inf), PoseRejection::kNotFinite);
  EXPECT_EQ(rejection_of(message_bytes(7, 100, {1, 2, 3}, {0, 0, 0, 1.1})), PoseRejection::kQuaternion);
  EXPECT_EQ(rejection_of(message_bytes(7, 100, {1, 2, 3}, {0, 0, 0, 0})), PoseRejection::kQuaternion);
  try {
    decode_pose_message(message_bytes(7, 100, {1, 2, 3}, {0, 0, 0, 2}));
  } catch (const PoseRejected& e) {
    EXPECT_STREQ(e.what(), "pose message 7: orientation qx qy qz qw must be a unit quaternion, its norm is 2.000000");
  }
}

TEST(PoseMessage, NormalizesAQuaternionWithinRounding) {
  const PoseMessage m = decode_pose_message(message_bytes(1, 1, {0, 0, 0}, {0, 0, 0, 1.0005}));
  EXPECT_DOUBLE_EQ(m.pose.rotation.norm(), 1.0);
}

}  // namespace
}  // namespace lidartwin
