// The forward model as a client would decode its packets: protocol units on the wire's steps,
// column windows, status words, timestamps and headers, columns without a pose, blank packets, and
// the same bytes for any thread count or packet split; and the worker pool a rig's sensors share.
#include <array>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/frame/forward_model.h"
#include "lidartwin/frame/packet_plan.h"
#include "lidartwin/frame/worker_pool.h"
#include "lidartwin/packet/lidar_packet.h"
#include "lidartwin/profile/sensor_profile.h"
#include "support/test_scene.h"

namespace lidartwin {
namespace {

constexpr uint32_t kInitId = 0x123456;
constexpr uint64_t kProdSn = 992200000042;

// A pose source that knows only [begin_s, end_s], as a live stream would.
class WindowedPoses final : public PoseSource {
 public:
  WindowedPoses(double begin_s, double end_s) : span_{begin_s, end_s} {}
  Pose at(double) const override { return Pose{}; }
  PoseSpan span() const override { return span_; }
  double start_s() const override { return span_.begin_s; }

 private:
  PoseSpan span_;
};

// A sensor driving through the room and spinning about its axis (a column's rays turn a third of
// the columns' spacing further), each column observed from its own place.
class MovingPoses final : public PoseSource {
 public:
  Pose at(double t) const override {
    Pose pose;
    pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(20.0 * t, Eigen::Vector3d::UnitZ()));
    pose.translation = Eigen::Vector3d(-2.0 + 10.0 * t, 1.0 - 5.0 * t, 0.2 * t);
    return pose;
  }
  PoseSpan span() const override { return {}; }
  double start_s() const override { return 0.0; }
};

class FrameTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::filesystem::temp_directory_path() / ("lidartwin_frame_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    // A closed 20 m x 20 m x 10 m room around the sensor: every beam hits a wall 5-14 m away.
    test::write_glb(dir_ / "room.glb", {test::box("room", {-10, -10, -5}, {10, 10, 5}, 0.3f)});
    scene_ = new Scene(Scene::load(dir_ / "room.glb"));
    // The same room with pillars in it: depth steps, where E6 reads the columns beside a pixel.
    test::write_glb(dir_ / "pillars.glb", {test::box("room", {-10, -10, -5}, {10, 10, 5}, 0.3f),
                                           test::box("pillar_a", {3, 2, -5}, {3.4, 2.4, 5}, 0.8f),
                                           test::box("pillar_b", {-4, -6, -5}, {-3.7, -5.7, 5}, 0.1f),
                                           test::box("pillar_c", {1, -3, -5}, {1.2, -2.8, 5}, 0.6f),
                                           test::box("pillar_d", {-2, 5, -5}, {-1.5, 5.5, 5}, 0.4f)});
    pillars_ = new Scene(Scene::load(dir_ / "pillars.glb"));
    profile_ = new SensorProfile(load_profile("os1-64"));
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete pillars_;
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

  static ForwardModelSetup setup(const LidarDataFormat& f, const nlohmann::json& chain) {
    ForwardModelSetup s;
    s.render = {profile_->beams, f, profile_->max_range_m, EffectChain::from_json(chain, "test chain"), 5, 1.0f};
    s.origin_ns = 1'000'000'000;
    s.init_id = kInitId;
    s.prod_sn = kProdSn;
    return s;
  }

  // Frame `frame` as the bytes of its packets, rendered whole or as the packet ranges [0, splits[0]),
  // [splits[0], splits[1]), ... in reverse order.
  static std::vector<uint8_t> render_bytes(const LidarDataFormat& f, int threads, const nlohmann::json& chain,
                                           uint64_t frame = 3, std::vector<size_t> splits = {},
                                           const PoseSource& poses = StaticPose(Pose{}), const Scene* scene = scene_) {
    WorkerPool pool(threads);
    const ForwardModel model(*scene, poses, setup(f, chain), pool);
    EncodedFrame encoded = model.make_frame_buffer();
    splits.insert(splits.begin(), 0);
    splits.push_back(model.packet_columns().size());
    for (size_t i = splits.size() - 1; i > 0; --i) model.render(frame, splits[i - 1], splits[i], encoded);
    return encoded.bytes;
  }

  // Frame `frame` decoded from its packets, as a client sees it.
  static Scan render(const LidarDataFormat& f, const nlohmann::json& chain, uint64_t frame = 3,
                     const PoseSource& poses = StaticPose(Pose{})) {
    WorkerPool pool(2);
    const ForwardModel model(*scene_, poses, setup(f, chain), pool);
    EncodedFrame encoded = model.make_frame_buffer();
    model.render(frame, encoded);
    return decode(model, encoded);
  }

  static Scan decode(const ForwardModel& model, const EncodedFrame& encoded) {
    const PacketFormat packets(model.format());
    Scan scan(model.format());
    for (size_t i = 0; i < model.packet_columns().size(); ++i) {
      std::string error;
      EXPECT_TRUE(packets.decode(model.packet(encoded, i), scan, &error).has_value()) << error;
    }
    return scan;
  }

  static inline std::filesystem::path dir_;
  static inline Scene* scene_ = nullptr;
  static inline Scene* pillars_ = nullptr;
  static inline SensorProfile* profile_ = nullptr;
};

const nlohmann::json kIdeal = nlohmann::json::parse(
    R"([{"name": "radiometry"}, {"name": "range_limits", "min_m": 0.3, "max_m": 100}, {"name": "range_quantization"}])");

TEST_F(FrameTest, AnyThreadCountGivesTheSameBytes) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  EXPECT_EQ(render_bytes(f, 1, profile_->effects), render_bytes(f, 3, profile_->effects));
}

TEST_F(FrameTest, AnyPacketSplitGivesTheSameBytes) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  EXPECT_EQ(render_bytes(f, 2, profile_->effects), render_bytes(f, 2, profile_->effects, 3, {7}));
}

// Workers walk runs of packets, and a packet's edge partners (E6) read the columns beside it from
// the next packet's own cast or, at a run's end, from a cast of that column alone. On a sensor that
// moves and turns, with pillars to make depth steps and the mount's jitter (E11) moving every
// column's rays, the two must be the same rays: the frame is the same bytes for any split of its
// packets into runs and any thread count.
TEST_F(FrameTest, EdgePartnersOfAMovingSensorDoNotDependOnHowPacketsAreSplit) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  nlohmann::json chain = profile_->effects;
  for (auto& effect : chain) {  // a footprint as wide as the beams' spacing: most edge pixels mix
    if (effect["name"] == "mixed_pixels") effect["divergence_rad"] = 0.012;
  }
  chain.push_back({{"name", "vibration"}, {"angular_rms_deg", 0.05}, {"translation_rms_m", 0.005}});
  const MovingPoses poses;
  const auto whole = render_bytes(f, 1, chain, 3, {}, poses, pillars_);
  EXPECT_TRUE(whole == render_bytes(f, 3, chain, 3, {}, poses, pillars_)) << "3 threads";
  EXPECT_TRUE(whole == render_bytes(f, 2, chain, 3, {1, 2, 5, 13, 14, 20, 31}, poses, pillars_)) << "split";
  std::vector<size_t> each;
  for (size_t i = 1; i < 32; ++i) each.push_back(i);
  EXPECT_TRUE(whole == render_bytes(f, 1, chain, 3, each, poses, pillars_)) << "a packet at a time";
  // The pillars' edges give mixed pixels: with a footprint of width 0 (the same noise streams, no
  // mixing) the frame differs.
  nlohmann::json without = chain;
  for (auto& effect : without) {
    if (effect["name"] == "mixed_pixels") effect["divergence_rad"] = 0.0;
  }
  const auto plain = render_bytes(f, 1, without, 3, {}, poses, pillars_);
  ASSERT_EQ(plain.size(), whole.size());
  size_t differ = 0;
  for (size_t i = 0; i < whole.size(); ++i) differ += plain[i] != whole[i];
  EXPECT_GT(differ, 100u) << "E6 should change the pixels at the pillars' edges";
}

TEST_F(FrameTest, HeadersCarryTheSensorsIdentityAndFrameId) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  const Scan scan = render(f, kIdeal, 70'001);
  EXPECT_EQ(scan.header.init_id, kInitId);
  EXPECT_EQ(scan.header.prod_sn, kProdSn);
  EXPECT_EQ(scan.header.frame_id, frame_id_of(70'001, f));
  EXPECT_EQ(scan.header.frame_id, 70'001u % 65'536u);
}

TEST_F(FrameTest, Rng15RangesAndNearIrSitOnTheirSteps) {
  const Scan scan = render(format(UdpProfileLidar::kRng15Rfl8Nir8), kIdeal);
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

// 6.4: only packets meeting the window are sent; their columns outside it are invalid and empty.
TEST_F(FrameTest, ColumnsOutsideTheWindowAreInvalidAndEmpty) {
  auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  f.column_window = {100, 200};
  const Scan scan = render(f, kIdeal);
  for (int m = 0; m < f.columns_per_frame; ++m) {
    const bool sent = m >= 96 && m < 208;
    EXPECT_EQ(scan.packet_received[static_cast<size_t>(m / 16)] != 0, sent) << m;
    if (!sent) continue;
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

TEST_F(FrameTest, LegacyValidColumnsAreAllOnes) {
  const Scan scan = render(format(UdpProfileLidar::kLegacy), kIdeal);
  for (const uint32_t status : scan.status) EXPECT_EQ(status, 0xFFFFFFFFu);
}

// 6.1, 6.3: column m at origin + frame start + floor(m * 1e9 / (W * fps)).
TEST_F(FrameTest, TimestampsFollowTheSensorClock) {
  const Scan scan = render(format(UdpProfileLidar::kRng19Rfl8Sig16Nir16), kIdeal);
  for (uint64_t m = 0; m < 512; ++m) {
    EXPECT_EQ(scan.timestamp_ns[m], 1'000'000'000ull + 300'000'000ull + m * 1'000'000'000ull / 5120);
  }
}

// A live source that has no pose yet for the second half of the frame: those columns go out on
// time, invalid and empty, instead of cast from a guess.
TEST_F(FrameTest, ColumnsWithoutAPoseAreInvalidAndEmpty) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  const WindowedPoses poses(0.0, 0.35);  // frame 3 runs from 0.3 s to 0.4 s
  const Scan scan = render(f, kIdeal, 3, poses);
  for (int m = 0; m < 512; ++m) {
    const bool has_pose = 0.3 + m / 5120.0 <= 0.35;
    EXPECT_EQ(scan.status[static_cast<size_t>(m)], has_pose ? 1u : 0u) << m;
    EXPECT_EQ(scan.column(ChannelField::kRange, m)[0] != 0, has_pose) << m;
  }
}

// What the daemon sends when rendering falls behind: on time, right ids, nothing valid.
TEST_F(FrameTest, BlankPacketsAreStampedButInvalid) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  WorkerPool pool(1);
  const StaticPose poses(Pose{});
  const ForwardModel model(*scene_, poses, setup(f, kIdeal), pool);
  EncodedFrame scratch = model.make_frame_buffer();
  const auto bytes = model.blank_packet(9, 2, scratch);
  Scan scan(f);
  const PacketFormat packets(f);
  ASSERT_TRUE(packets.decode(bytes, scan, nullptr).has_value());
  EXPECT_EQ(scan.header.frame_id, 9u);
  EXPECT_EQ(scan.header.init_id, kInitId);
  for (int m = 32; m < 48; ++m) {
    EXPECT_EQ(scan.status[static_cast<size_t>(m)], 0u);
    EXPECT_EQ(scan.timestamp_ns[static_cast<size_t>(m)], model.clock().column_timestamp_ns(9, m));
    for (const uint32_t range : scan.column(ChannelField::kRange, m)) EXPECT_EQ(range, 0u);
  }
  EXPECT_EQ(model.packet_timestamp_ns(9, 2), model.clock().column_timestamp_ns(9, 47));
}

TEST_F(FrameTest, ImuPacketsShareTheLidarClock) {
  const auto f = format(UdpProfileLidar::kRng19Rfl8Sig16Nir16);
  WorkerPool pool(1);
  const StaticPose poses(Pose{});
  const ForwardModel model(*scene_, poses, setup(f, kIdeal), pool);
  std::array<uint8_t, kLegacyImuPacketSize> bytes{};
  model.imu_packet(12, bytes);
  const auto sample = decode_legacy_imu(bytes);
  ASSERT_TRUE(sample.has_value());
  EXPECT_EQ(sample->sys_ts_ns, 1'000'000'000u + 12 * kImuPeriodNs);
  EXPECT_NEAR(sample->accel_g[2], 1.0f, 1e-6f);  // at rest, Z up
}

// A rig's sensors render on one pool at once: each caller's items all run, once each, and no two
// threads of one run share a worker index (per-worker scratch is indexed by it).
TEST(WorkerPool, SeveralCallersRunAtOnceEachItemOnceWithDistinctWorkers) {
  WorkerPool pool(3);
  constexpr int kCallers = 4;
  constexpr int kItems = 200;
  std::vector<std::vector<std::atomic<int>>> runs(kCallers);
  std::atomic<bool> shared_index{false};
  std::vector<std::thread> callers;
  for (int c = 0; c < kCallers; ++c) {
    runs[static_cast<size_t>(c)] = std::vector<std::atomic<int>>(kItems);
    callers.emplace_back([&, c] {
      std::array<std::atomic<int>, 3> in_use{};
      pool.run(kItems, [&](int worker, int item) {
        if (in_use[static_cast<size_t>(worker)].fetch_add(1) != 0) shared_index = true;
        ++runs[static_cast<size_t>(c)][static_cast<size_t>(item)];
        in_use[static_cast<size_t>(worker)].fetch_sub(1);
      });
    });
  }
  for (auto& caller : callers) caller.join();
  for (const auto& run : runs)
    for (const auto& count : run) EXPECT_EQ(count.load(), 1);
  EXPECT_FALSE(shared_index.load());
}

// On a busy host a worker may not run for milliseconds: a caller does its items itself rather than
// wait for a worker that has not started on them. Here the only worker is stuck in another
// caller's item, and a second caller's run still completes.
TEST(WorkerPool, ACallerNeverWaitsForAWorkerBusyElsewhere) {
  WorkerPool pool(2);
  std::promise<void> release;
  const std::shared_future<void> released = release.get_future().share();
  std::atomic<int> stuck{0};
  std::thread blocked([&] {
    pool.run(2, [&](int, int) {
      ++stuck;
      released.wait();
    });
  });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (stuck.load() < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
  if (stuck.load() < 2) release.set_value();
  ASSERT_EQ(stuck.load(), 2) << "the worker never took the blocked caller's second item";  // both are held
  auto second = std::async(std::launch::async, [&] {
    int done = 0;
    pool.run(5, [&](int, int) { ++done; });
    return done;
  });
  EXPECT_EQ(second.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  release.set_value();
  blocked.join();
  EXPECT_EQ(second.get(), 5);
}

TEST(WorkerPool, RethrowsTheFirstExceptionToItsCaller) {
  WorkerPool pool(2);
  EXPECT_THROW(pool.run(10,
                        [](int, int item) {
                          if (item == 3) throw std::runtime_error("item 3");
                        }),
               std::runtime_error);
  int done = 0;
  pool.run(1, [&](int, int) { ++done; });  // and stays usable
  EXPECT_EQ(done, 1);
}

}  // namespace
}  // namespace lidartwin
