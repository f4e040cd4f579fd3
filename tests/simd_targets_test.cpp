// Acceptance (issue 25): the per-pixel SIMD kernels run on whichever Highway target the CPU has
// (SSSE3, SSE4, AVX2, AVX-512, NEON...), and the same seed gives the same capture bytes on every
// one, so a farm of mixed CPUs records identical captures. Each capture here is recorded once per
// target that Highway compiled and this CPU runs (hwy::SetSupportedTargetsForTest forces it) and
// compared byte for byte with the first; the profiles cover every pixel size the kernels
// interleave differently (LEGACY and RNG19: 12 bytes, DUAL: 16, RNG15: 4) and every effect.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <hwy/targets.h>
#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_source.h"
#include "lidartwin/profile/sensor_profile.h"
#include "lidartwin/record/recorder.h"
#include "lidartwin/scene/scene.h"
#include "support/every_effect_chain.h"

namespace lidartwin {
namespace {

const std::filesystem::path kSource = LIDARTWIN_SOURCE_DIR;

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct Case {
  const char* profile;
  const char* mode;
  const char* udp_profile;
  bool every_effect;  // the profile's own chain, or every library effect on
};

class SimdTargets : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lidartwin_simd_targets_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    hwy::SetSupportedTargetsForTest(0);  // back to what the CPU supports
    std::filesystem::remove_all(dir_);
  }

  // Two frames of the plant flight, two threads, written under dir_/name; the capture's bytes.
  std::string record_capture(const Case& c, const std::string& name) const {
    const SensorProfile profile = load_profile(c.profile);
    nlohmann::json config = default_config_params();
    config["lidar_mode"] = c.mode;
    config["udp_profile_lidar"] = c.udp_profile;
    SensorInfo info;
    info.prod_sn = "992200000001";
    info.initialization_id = 7;
    const EffectChain chain = EffectChain::from_json(
        c.every_effect ? test::every_effect_chain(test::range_noise_of(profile.effects)) : profile.effects,
        "test chain");
    const Scene scene = Scene::load(kSource / "scenes/plant.glb");
    const TrajectoryPoses poses(Trajectory::load_tum(kSource / "scenes/plant_inspection.tum"));
    const Recording recording{.scene = scene,
                              .poses = poses,
                              .max_range_m = profile.max_range_m,
                              .chain = chain,
                              .metadata = make_metadata(info, profile.beams, config),
                              .seed = 7,
                              .threads = 2,
                              .frames = 2,
                              .out_dir = dir_ / name,
                              .imu_noise = profile.imu};
    EXPECT_EQ(record(recording, [](int) {}), 2);
    return file_bytes(recording.out_dir / "capture.pcap");
  }

  std::filesystem::path dir_;
};

TEST_P(SimdTargets, EveryTargetRecordsTheSameBytes) {
  const Case& c = GetParam();
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  std::string reference;
  std::string reference_name;
  for (const int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    const std::string name = hwy::TargetName(target);
    const std::string bytes = record_capture(c, name);
    std::printf("  %-8s %zu bytes\n", name.c_str(), bytes.size());
    ASSERT_GT(bytes.size(), 100000u) << name;
    if (reference.empty()) {
      reference = bytes;
      reference_name = name;
      continue;
    }
    ASSERT_EQ(bytes.size(), reference.size()) << name << " against " << reference_name;
    size_t first_difference = 0;
    while (first_difference < bytes.size() && bytes[first_difference] == reference[first_difference]) {
      ++first_difference;
    }
    EXPECT_EQ(first_difference, bytes.size())
        << name << " differs from " << reference_name << " from byte " << first_difference;
  }
}

INSTANTIATE_TEST_SUITE_P(Profiles, SimdTargets,
                         ::testing::Values(Case{"os1-128", "1024x10", "RNG19_RFL8_SIG16_NIR16", false},
                                           Case{"os1-64", "1024x10", "RNG19_RFL8_SIG16_NIR16_DUAL", true},
                                           Case{"os0-32", "512x10", "RNG15_RFL8_NIR8", true},
                                           Case{"os2-64", "512x10", "LEGACY", false}),
                         [](const auto& param_info) {
                           std::string name =
                               std::string(param_info.param.profile) + "_" + param_info.param.udp_profile;
                           for (char& ch : name) {
                             if (ch == '-') ch = '_';
                           }
                           return name;
                         });

}  // namespace
}  // namespace lidartwin
