// FrameRenderer: protocol units on the wire's steps, column windows, status words, timestamps,
// and the same scan for any thread count.
#include <filesystem>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/render/frame_renderer.h"
#include "support/test_scene.h"

namespace lidartwin {
namespace {

class RenderTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::filesystem::temp_directory_path() / ("lidartwin_render_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    // A closed 20 m x 20 m x 10 m room around the sensor: every beam hits a wall 5-14 m away.
    test::write_glb(dir_ / "room.glb", {test::box("room", {-10, -10, -5}, {10, 10, 5}, 0.3f)});
    scene_ = new Scene(Scene::load(dir_ / "room.glb"));
    profile_ = new SensorProfile(load_profile("os1-64"));
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete profile_;
    std::filesystem::remove_all(dir_);
  }

  static LidarDataFormat format(UdpProfileLidar profile) {
    LidarDataFormat f;
    f.udp_profile_lidar = profile;
    f.pixels_per_column = 64;
    f.columns_per_frame = 512;
    f.fps = 10;
    f.column_window = {0, 511};
    f.pixel_shift_by_row.assign(64, 0);
    return f;
  }

  static Scan render(const LidarDataFormat& f, int threads, const nlohmann::json& chain, uint64_t frame = 3) {
    RenderConfig config;
    config.seed = 5;
    config.threads = threads;
    config.clock_origin_ns = 1'000'000'000;
    const FrameRenderer renderer(*scene_, *profile_, EffectChain::from_json(chain, "test chain"), f, config);
    Scan scan(f);
    renderer.render(frame, 0.3, Trajectory::constant(Pose{}), 0, f.columns_per_frame, scan);
    return scan;
  }

  static inline std::filesystem::path dir_;
  static inline Scene* scene_ = nullptr;
  static inline SensorProfile* profile_ = nullptr;
};

const nlohmann::json kIdeal = nlohmann::json::parse(
    R"([{"name": "radiometry"}, {"name": "range_limits", "min_m": 0.3, "max_m": 100}, {"name": "range_quantization"}])");

TEST_F(RenderTest, AnyThreadCountGivesTheSameScan) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  const Scan one = render(f, 1, profile_->effects);
  const Scan three = render(f, 3, profile_->effects);
  EXPECT_EQ(one.channels, three.channels);
  EXPECT_EQ(one.timestamp_ns, three.timestamp_ns);
  EXPECT_EQ(one.status, three.status);
}

TEST_F(RenderTest, Rng15RangesAndNearIrSitOnTheirSteps) {
  const auto f = format(UdpProfileLidar::kRng15Rfl8Nir8);
  const Scan scan = render(f, 2, kIdeal);
  size_t returns = 0;
  for (const uint32_t range : scan.channels[static_cast<size_t>(ChannelField::kRange)]) {
    EXPECT_EQ(range % 8, 0u);
    returns += range != 0;
  }
  EXPECT_EQ(returns, scan.channels[0].size());  // the room closes every beam
  for (const uint32_t nir : scan.channels[static_cast<size_t>(ChannelField::kNearIr)]) {
    EXPECT_EQ(nir % 16, 0u);
    EXPECT_LE(nir, 4080u);
  }
  for (const uint32_t reflectivity : scan.channels[static_cast<size_t>(ChannelField::kReflectivity)]) {
    EXPECT_LE(reflectivity, 255u);
  }
}

TEST_F(RenderTest, ColumnsOutsideTheWindowAreInvalidAndEmpty) {
  auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  f.column_window = {100, 200};
  const Scan scan = render(f, 2, kIdeal);
  for (int m = 0; m < f.columns_per_frame; ++m) {
    const bool inside = m >= 100 && m <= 200;
    EXPECT_EQ(scan.status[static_cast<size_t>(m)], inside ? 1u : 0u) << m;
    const auto ranges = scan.column(ChannelField::kRange, m);
    const auto signal = scan.column(ChannelField::kSignal, m);
    for (int r = 0; r < 64; ++r) {
      EXPECT_EQ(ranges[static_cast<size_t>(r)] != 0, inside) << m << "," << r;
      if (!inside) {
        EXPECT_EQ(signal[static_cast<size_t>(r)], 0u);
      }
    }
  }
}

TEST_F(RenderTest, LegacyValidColumnsAreAllOnes) {
  const Scan scan = render(format(UdpProfileLidar::kLegacy), 2, kIdeal);
  for (const uint32_t status : scan.status) EXPECT_EQ(status, 0xFFFFFFFFu);
}

// 6.1, 6.3: column m at clock_origin + frame start + floor(m * 1e9 / (W * fps)).
TEST_F(RenderTest, TimestampsFollowTheColumnClock) {
  const Scan scan = render(format(UdpProfileLidar::kRng19Rfl8Sig16Nir16), 2, kIdeal);
  for (uint64_t m = 0; m < 512; ++m) {
    EXPECT_EQ(scan.timestamp_ns[m], 1'000'000'000ull + 300'000'000ull + m * 1'000'000'000ull / 5120);
  }
}

}  // namespace
}  // namespace lidartwin
