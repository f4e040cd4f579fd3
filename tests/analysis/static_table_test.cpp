// Static mode's table on a real motionless capture (crc_test.pcap, an OS-0-128): what the unit's
// configuration says about its SIGNAL reaches the prediction, as in the scene and map tables.
#include <string>

#include <gtest/gtest.h>

#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/analysis/static_table.h"
#include "lidartwin/error.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin {
namespace {

const std::string kSamples = std::string(LIDARTWIN_SOURCE_DIR) + "/tests/data/ouster-samples/";

// A unit configured with signal_multiplier 2 reports twice the SIGNAL for the same light (E18):
// the expected signal of every pixel doubles, and with it the spread E2 predicts falls.
TEST(StaticTable, TheUnitsSignalMultiplierScalesTheExpectedSignal) {
  const MeasuredCapture capture = read_capture(kSamples + "crc_test.pcap", kSamples + "crc_test.json");
  MeasuredCapture doubled = capture;
  doubled.metadata.config_params["signal_multiplier"] = 2;
  const SensorProfile profile = load_profile("os0-128");
  const EffectChain chain = EffectChain::from_json(profile.effects, "os0-128");
  const PixelTable one = build_static_table({capture, chain, profile.max_range_m});
  const PixelTable two = build_static_table({doubled, chain, profile.max_range_m});
  ASSERT_EQ(one.size(), two.size());
  ASSERT_GT(one.size(), 1000u);
  size_t spread_fell = 0;
  for (size_t i = 0; i < one.size(); ++i) {
    ASSERT_GT(one.expected_signal[i], 0.0f) << i;
    ASSERT_FLOAT_EQ(two.expected_signal[i], 2.0f * one.expected_signal[i]) << i;
    spread_fell += two.predicted_sigma_m[i] < one.predicted_sigma_m[i];
  }
  EXPECT_GT(spread_fell, one.size() / 2);  // os0-128 carries E2: sigma^2 = floor^2 + k^2 / S
}

// The real OS-1-128 sample travels 0.75 m over its three frames: static mode refuses it, with the
// motion it found, rather than scoring the motion as spread (it read +4,347 standard errors).
TEST(StaticTable, AMovingSensorIsRefusedWithTheMotionFound) {
  const MeasuredCapture capture =
      read_capture(kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap", kSamples + "OS-1-128_v2.3.0_1024x10.json");
  const SensorProfile profile = load_profile("os1-128");
  const EffectChain chain = EffectChain::from_json(profile.effects, "os1-128");
  try {
    build_static_table({capture, chain, profile.max_range_m});
    FAIL() << "a moving capture was taken as motionless";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("--static: the sensor moved: between frame 0 and frame 2 the range of "), std::string::npos)
        << message;
    EXPECT_NE(message.find("compare with --map"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace lidartwin
