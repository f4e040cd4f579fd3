// The sensor state machine without HTTP: validation (never half-applied), "@auto", reinit,
// subscribers, persistence (protocol doc 2.6, 2.7).
#include <unistd.h>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "lidartwin/error.h"
#include "lidartwin/sensor/sensor.h"

namespace {

using lidartwin::InputError;
using lidartwin::Sensor;
using lidartwin::SensorIdentity;
using lidartwin::SensorOptions;
using nlohmann::json;
using testing::HasSubstr;

// An OS-1-64-like product: 64 beams, staggered azimuths as on a real Gen-1 sensor.
SensorIdentity test_identity() {
  SensorIdentity identity;
  for (int row = 0; row < 64; ++row) {
    identity.beams.altitude_deg.push_back(16.6 - 0.52 * row);
    identity.beams.azimuth_deg.push_back(std::array{3.1, 0.9, -1.2, -3.3}[row % 4]);
  }
  identity.beams.lidar_origin_to_beam_origin_mm = 12.163;
  identity.limits.lidar_modes = {"512x10", "512x20", "1024x10", "1024x20", "2048x10"};
  return identity;
}

// A fresh directory per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("lidartwin_sensor_test_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

TEST(Sensor, StartsWithFirmwareDefaultsActiveAndStagedEqual) {
  Sensor sensor(test_identity());
  const auto active = sensor.active_config();
  EXPECT_EQ(active.at("lidar_mode"), "1024x10");
  EXPECT_EQ(active.at("udp_dest"), "127.0.0.1");
  EXPECT_EQ(active.at("udp_port_lidar"), 7502);
  EXPECT_EQ(active.at("udp_port_imu"), 7503);
  EXPECT_EQ(sensor.staged_config(), active);
  EXPECT_EQ(sensor.status(), "RUNNING");
  const auto stream = sensor.stream_config();
  EXPECT_EQ(stream->generation, 1u);
  EXPECT_NE(stream->init_id, 0u);
  EXPECT_LT(stream->init_id, 1u << 24);
  EXPECT_EQ(stream->prod_sn, 122201000123u);
  EXPECT_EQ(sensor.sensor_info().at("initialization_id"), stream->init_id);
}

TEST(Sensor, MetadataHasAllSevenSectionsAndImuDataFormat) {
  Sensor sensor(test_identity());
  const auto metadata = sensor.metadata();
  for (const char* section : {"sensor_info", "beam_intrinsics", "imu_intrinsics", "lidar_intrinsics", "config_params",
                              "lidar_data_format", "calibration_status", "imu_data_format"}) {
    EXPECT_TRUE(metadata.contains(section)) << section;
    ASSERT_TRUE(sensor.metadata_section(section).has_value()) << section;
    EXPECT_EQ(*sensor.metadata_section(section), metadata.at(section)) << section;
  }
  EXPECT_FALSE(sensor.metadata_section("no_such_section").has_value());
  EXPECT_EQ(metadata.at("sensor_info").at("image_rev"), "ousteros-image-prod-bootes-v3.1.0+20240426041747");
  EXPECT_EQ(metadata.at("sensor_info").at("prod_sn"), "122201000123");
}

TEST(Sensor, WriteStagedMergesKeepsUnknownKeysAndLeavesActive) {
  Sensor sensor(test_identity());
  const auto active_before = sensor.active_config();
  sensor.write_staged({{"lidar_mode", "2048x10"}, {"vendor_extra", {{"a", 1}}}}, "127.0.0.1");
  const auto staged = sensor.staged_config();
  EXPECT_EQ(staged.at("lidar_mode"), "2048x10");
  EXPECT_EQ(staged.at("vendor_extra"), json({{"a", 1}}));
  EXPECT_EQ(staged.at("udp_port_lidar"), 7502);  // untouched keys stay
  EXPECT_EQ(sensor.active_config(), active_before);
  sensor.reinit();
  EXPECT_EQ(sensor.active_config().at("vendor_extra"), json({{"a", 1}}));
}

struct BadWrite {
  json partial;
  std::string key;
  friend void PrintTo(const BadWrite& write, std::ostream* out) { *out << write.partial.dump(); }
};

class SensorRejects : public testing::TestWithParam<BadWrite> {};

TEST_P(SensorRejects, NamesTheKeyAndChangesNothing) {
  Sensor sensor(test_identity());
  const auto staged = sensor.staged_config();
  const auto active = sensor.active_config();
  try {
    sensor.write_staged(GetParam().partial, "127.0.0.1");
    FAIL() << "accepted " << GetParam().partial.dump();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(GetParam().key)) << e.what();
  }
  EXPECT_EQ(sensor.staged_config(), staged);
  EXPECT_EQ(sensor.active_config(), active);
}

INSTANTIATE_TEST_SUITE_P(
    Config, SensorRejects,
    testing::Values(
        BadWrite{{{"lidar_mode", "1024x15"}}, "lidar_mode"}, BadWrite{{{"lidar_mode", "3000x10"}}, "lidar_mode"},
        BadWrite{{{"lidar_mode", "4096x5"}}, "lidar_mode"},  // not in this product's modes
        BadWrite{{{"lidar_mode", 1024}}, "lidar_mode"}, BadWrite{{{"udp_profile_lidar", "RNG99"}}, "udp_profile_lidar"},
        BadWrite{{{"udp_profile_imu", "FAST"}}, "udp_profile_imu"},
        BadWrite{{{"columns_per_packet", 3}}, "columns_per_packet"},
        BadWrite{{{"columns_per_packet", 128}}, "columns_per_packet"},
        BadWrite{{{"azimuth_window", {0}}}, "azimuth_window"},
        BadWrite{{{"azimuth_window", {-1, 1000}}}, "azimuth_window"},
        BadWrite{{{"azimuth_window", {0, 360001}}}, "azimuth_window"},
        BadWrite{{{"azimuth_window", "0,360000"}}, "azimuth_window"},
        BadWrite{{{"signal_multiplier", 1.5}}, "signal_multiplier"},
        BadWrite{{{"udp_port_lidar", 65536}}, "udp_port_lidar"}, BadWrite{{{"udp_port_imu", -1}}, "udp_port_imu"},
        BadWrite{{{"udp_port_lidar", "7502"}}, "udp_port_lidar"},
        BadWrite{{{"udp_port_lidar", 7502.5}}, "udp_port_lidar"}, BadWrite{{{"udp_dest", "1.2.3"}}, "udp_dest"},
        BadWrite{{{"udp_dest", ""}}, "udp_dest"}, BadWrite{{{"udp_dest", "::1"}}, "udp_dest"},
        BadWrite{{{"udp_dest", 17}}, "udp_dest"}, BadWrite{{{"udp_dest", nullptr}}, "udp_dest"},
        BadWrite{{{"udp_dest", "no-such-host.invalid"}}, "udp_dest"},
        BadWrite{{{"operating_mode", "OFF"}}, "operating_mode"},
        BadWrite{{{"timestamp_mode", "TIME_FROM_ROS_TIME"}}, "timestamp_mode"},
        BadWrite{{{"lidar_frame_azimuth_offset", 360001}}, "lidar_frame_azimuth_offset"},
        BadWrite{{{"phase_lock_enable", "yes"}}, "phase_lock_enable"},
        BadWrite{{{"nmea_ignore_valid_char", 2}}, "nmea_ignore_valid_char"},
        BadWrite{{{"multipurpose_io_mode", "ON"}}, "multipurpose_io_mode"},
        BadWrite{{{"sync_pulse_out_angle", 361}}, "sync_pulse_out_angle"},
        // Valid keys next to one bad key: the whole write is refused.
        BadWrite{{{"lidar_mode", "2048x10"}, {"udp_port_lidar", 70000}}, "udp_port_lidar"}));

TEST(Sensor, ErrorNamesEveryBadKey) {
  Sensor sensor(test_identity());
  try {
    sensor.write_staged({{"lidar_mode", "9x9"}, {"udp_port_imu", "x"}, {"fine_unknown", 1}}, "127.0.0.1",
                        "POST sensor/config");
    FAIL();
  } catch (const InputError& e) {
    // Each problem in json_reader's form: the request, the JSON pointer, what was expected.
    EXPECT_THAT(e.what(), HasSubstr("POST sensor/config: /lidar_mode: must be a lidar mode of this sensor: "));
    EXPECT_THAT(e.what(),
                HasSubstr(R"(POST sensor/config: /udp_port_imu: must be an integer in [0, 65535], got a string "x")"));
    EXPECT_THAT(e.what(), testing::Not(HasSubstr("fine_unknown")));
  }
}

TEST(Sensor, RejectsABodyThatIsNotAnObject) {
  Sensor sensor(test_identity());
  EXPECT_THROW(sensor.write_staged(json::array({1, 2}), "127.0.0.1"), InputError);
  EXPECT_THROW(sensor.write_staged("udp_dest", "127.0.0.1"), InputError);
}

TEST(Sensor, AutoResolvesToThePeerAtWriteTime) {
  SensorOptions options;
  options.config_overrides = {{"udp_dest", "192.0.2.1"}};
  Sensor sensor(test_identity(), options);
  sensor.write_staged({{"udp_dest", "@auto"}}, "10.1.2.3");
  EXPECT_EQ(sensor.staged_config().at("udp_dest"), "10.1.2.3");
  sensor.write_staged({{"udp_dest", "@auto"}}, "::ffff:127.0.0.1");  // dual-stack socket
  EXPECT_EQ(sensor.staged_config().at("udp_dest"), "127.0.0.1");
  sensor.write_staged({{"udp_dest", "@auto"}}, "::1");
  EXPECT_EQ(sensor.staged_config().at("udp_dest"), "127.0.0.1");
  sensor.write_staged({{"udp_dest_zm", "@auto"}}, "10.9.8.7");
  EXPECT_EQ(sensor.staged_config().at("udp_dest_zm"), "10.9.8.7");
  EXPECT_THROW(sensor.write_staged({{"udp_dest", "@auto"}}, ""), InputError);
  EXPECT_THROW(sensor.write_staged({{"udp_dest", "@auto"}}, "2001:db8::1"), InputError);
  EXPECT_EQ(sensor.active_config().at("udp_dest"), "192.0.2.1");  // only staged changes
}

TEST(Sensor, HostNamesResolveToIpv4AtWriteTime) {
  Sensor sensor(test_identity());
  sensor.write_staged({{"udp_dest", "localhost"}}, "127.0.0.1");
  EXPECT_EQ(sensor.staged_config().at("udp_dest"), "127.0.0.1");
}

TEST(Sensor, UdpIpAndUdpDestStayConsistent) {
  Sensor sensor(test_identity());
  sensor.write_staged({{"udp_ip", "@auto"}}, "10.0.0.5");  // FW 2.0/2.1 name
  EXPECT_EQ(sensor.staged_config().at("udp_ip"), "10.0.0.5");
  EXPECT_EQ(sensor.staged_config().at("udp_dest"), "10.0.0.5");
  sensor.write_staged({{"udp_dest", "10.0.0.6"}}, "10.0.0.5");
  EXPECT_EQ(sensor.staged_config().at("udp_ip"), "10.0.0.6");
}

TEST(Sensor, ReinitActivatesStagedWithNewInitIdAndDerivedFormat) {
  Sensor sensor(test_identity());
  std::vector<Sensor::StreamConfigPtr> seen;
  sensor.subscribe([&](const Sensor::StreamConfigPtr& config) { seen.push_back(config); });
  ASSERT_EQ(seen.size(), 1u);  // called at once with the current config
  const auto first = seen.back();

  sensor.write_staged({{"lidar_mode", "2048x10"},
                       {"udp_dest", "10.1.2.3"},
                       {"udp_port_lidar", 40001},
                       {"udp_port_imu", 0},
                       {"signal_multiplier", 0.5},
                       {"lidar_frame_azimuth_offset", 9000},
                       {"timestamp_mode", "TIME_FROM_PTP_1588"}},
                      "127.0.0.1");
  EXPECT_EQ(seen.size(), 1u);  // writing staged does not restart the stream
  sensor.reinit();
  ASSERT_EQ(seen.size(), 2u);
  const auto& next = *seen.back();
  EXPECT_EQ(next.generation, first->generation + 1);
  EXPECT_NE(next.init_id, first->init_id);
  EXPECT_EQ(next.metadata.sensor_info.initialization_id, next.init_id);
  EXPECT_EQ(next.metadata.format.columns_per_frame, 2048);
  EXPECT_EQ(next.metadata.format.fps, 10);
  EXPECT_EQ(next.metadata.format.column_window, (std::array<int, 2>{0, 2047}));
  EXPECT_EQ(next.udp_dest, (std::array<uint8_t, 4>{10, 1, 2, 3}));
  EXPECT_EQ(next.udp_port_lidar, 40001);
  EXPECT_EQ(next.udp_port_imu, 0);
  EXPECT_TRUE(next.streaming);
  EXPECT_EQ(next.timestamp_mode, "TIME_FROM_PTP_1588");
  EXPECT_EQ(next.signal_multiplier, 0.5f);
  // lidar_frame_azimuth_offset reaches the stream as the served beams, rotated (make_metadata).
  EXPECT_NE(next.metadata.beams.lidar_to_sensor, first->metadata.beams.lidar_to_sensor);
  EXPECT_EQ(sensor.sensor_info().at("initialization_id"), next.init_id);
  EXPECT_EQ(sensor.metadata().at("lidar_data_format").at("columns_per_frame"), 2048);
  EXPECT_EQ(sensor.active_config(), sensor.staged_config());
}

// Protocol doc 3.3/6.4: the real FW 2.5.0 file has azimuth_window [583, 39402] -> [912, 1022]
// at 1024x10.
TEST(Sensor, ColumnWindowFollowsAzimuthWindowAsTheFirmwareReports) {
  Sensor sensor(test_identity());
  sensor.write_staged({{"azimuth_window", {583, 39402}}}, "127.0.0.1");
  sensor.reinit();
  EXPECT_EQ(sensor.stream_config()->metadata.format.column_window, (std::array<int, 2>{912, 1022}));
  EXPECT_EQ(sensor.metadata().at("lidar_data_format").at("column_window"), json({912, 1022}));
}

TEST(Sensor, StandbyStopsStreamingAndReportsStandby) {
  Sensor sensor(test_identity());
  sensor.write_staged({{"operating_mode", "STANDBY"}}, "127.0.0.1");
  sensor.reinit();
  EXPECT_FALSE(sensor.stream_config()->streaming);
  EXPECT_EQ(sensor.status(), "STANDBY");
}

TEST(Sensor, EveryReinitGetsANew24BitInitId) {
  Sensor sensor(test_identity());
  uint32_t previous = sensor.stream_config()->init_id;
  for (int i = 0; i < 200; ++i) {
    sensor.reinit();
    const uint32_t id = sensor.stream_config()->init_id;
    EXPECT_NE(id, previous);
    EXPECT_NE(id, 0u);
    EXPECT_LT(id, 1u << 24);
    previous = id;
  }
  EXPECT_EQ(sensor.stream_config()->generation, 201u);
}

TEST(Sensor, UnsubscribedCallbacksAreNotCalled) {
  Sensor sensor(test_identity());
  int calls = 0;
  const int id = sensor.subscribe([&](const Sensor::StreamConfigPtr&) { ++calls; });
  sensor.reinit();
  sensor.unsubscribe(id);
  sensor.reinit();
  EXPECT_EQ(calls, 2);
}

TEST(Sensor, SubscribersSeeGenerationsInOrderUnderConcurrentReinits) {
  Sensor sensor(test_identity());
  std::vector<uint64_t> generations;
  sensor.subscribe([&](const Sensor::StreamConfigPtr& c) {
    generations.push_back(c->generation);
    (void)sensor.sensor_info();  // the read side is usable from a callback
  });
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 25; ++i) sensor.reinit();
    });
  }
  for (auto& thread : threads) thread.join();
  ASSERT_EQ(generations.size(), 101u);
  for (size_t i = 1; i < generations.size(); ++i) EXPECT_EQ(generations[i], generations[i - 1] + 1);
}

TEST(Sensor, InitializingStatusIsBrief) {
  SensorOptions options;
  options.initializing_time = std::chrono::milliseconds(150);
  Sensor sensor(test_identity(), options);
  sensor.reinit();
  EXPECT_EQ(sensor.status(), "INITIALIZING");
  EXPECT_EQ(sensor.metadata().at("sensor_info").at("status"), "INITIALIZING");
  std::this_thread::sleep_for(std::chrono::milliseconds(250));
  EXPECT_EQ(sensor.sensor_info().at("status"), "RUNNING");
}

TEST(Sensor, PersistedConfigAndUserDataAreRestoredOnTheNextStart) {
  TempDir dir;
  SensorOptions options;
  options.state_file = dir.path() / "state.json";
  {
    Sensor sensor(test_identity(), options);
    sensor.write_staged({{"lidar_mode", "2048x10"}, {"vendor_extra", "kept"}}, "127.0.0.1");
    sensor.reinit();
    sensor.persist();
    sensor.set_user_data("hello", lidartwin::UserDataPolicy::kKeepOnConfigDelete);
    // Activated but not persisted: must not survive.
    sensor.write_staged({{"udp_port_lidar", 9999}}, "127.0.0.1");
    sensor.reinit();
  }
  EXPECT_TRUE(std::filesystem::exists(options.state_file));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()),
            1);  // no temporary file left behind
  Sensor restored(test_identity(), options);
  EXPECT_EQ(restored.active_config().at("lidar_mode"), "2048x10");
  EXPECT_EQ(restored.active_config().at("vendor_extra"), "kept");
  EXPECT_EQ(restored.active_config().at("udp_port_lidar"), 7502);
  EXPECT_EQ(restored.stream_config()->metadata.format.columns_per_frame, 2048);
  EXPECT_EQ(restored.user_data().value, "hello");
  EXPECT_EQ(restored.user_data().policy, lidartwin::UserDataPolicy::kKeepOnConfigDelete);
}

TEST(Sensor, OverridesApplyOverTheSavedConfigWithoutBeingSaved) {
  TempDir dir;
  SensorOptions options;
  options.state_file = dir.path() / "state.json";
  options.config_overrides = {{"udp_port_lidar", 8000}};
  {
    Sensor sensor(test_identity(), options);
    EXPECT_EQ(sensor.active_config().at("udp_port_lidar"), 8000);
  }
  EXPECT_FALSE(std::filesystem::exists(options.state_file));
}

TEST(Sensor, BadStartInputsNameTheirSource) {
  TempDir dir;
  SensorOptions options;
  options.state_file = dir.path() / "state.json";
  std::ofstream(options.state_file) << "{ not json";
  EXPECT_THAT([&] { Sensor sensor(test_identity(), options); },
              testing::ThrowsMessage<InputError>(HasSubstr("state.json")));
  std::ofstream(options.state_file, std::ios::trunc) << R"({"lidartwin_state": 1, "config": {"lidar_mode": "77x7"}})";
  EXPECT_THAT([&] { Sensor sensor(test_identity(), options); },
              testing::ThrowsMessage<InputError>(HasSubstr("state.json: /config/lidar_mode: must be a lidar mode")));
  std::ofstream(options.state_file, std::ios::trunc) << R"({"lidartwin_state": 1, "config": {}, "user_data": 7})";
  EXPECT_THAT(
      [&] { Sensor sensor(test_identity(), options); },
      testing::ThrowsMessage<InputError>(HasSubstr("state.json: /user_data: must be a string, got a number 7")));

  SensorOptions overrides;
  overrides.config_overrides = {{"udp_dest", "@auto"}};  // no HTTP peer at start
  EXPECT_THAT([&] { Sensor sensor(test_identity(), overrides); },
              testing::ThrowsMessage<InputError>(HasSubstr("udp_dest")));
  auto identity = test_identity();
  identity.prod_sn = "OS123";
  EXPECT_THAT([&] { Sensor sensor(identity); }, testing::ThrowsMessage<InputError>(HasSubstr("prod_sn")));
}

TEST(Sensor, UserDataDefaultsToEmptyAndCanBeDeleted) {
  Sensor sensor(test_identity());
  EXPECT_EQ(sensor.user_data().value, "");
  sensor.set_user_data("x", lidartwin::UserDataPolicy::kClearOnConfigDelete);
  EXPECT_EQ(sensor.user_data().value, "x");
  sensor.delete_user_data();
  EXPECT_EQ(sensor.user_data().value, "");
}

TEST(ConfigRules, FirmwareDefaultsAndTheProtocolDocExampleAreValid) {
  const lidartwin::json_reader::Location body{"POST sensor/config", ""};
  EXPECT_THAT(lidartwin::config_errors(lidartwin::default_config_params(), {}, body), testing::IsEmpty());
  // SDK-written values (protocol doc 2.4 (a)): integers for multipliers >= 1, 0/1 flags.
  auto config = lidartwin::default_config_params();
  config.update({{"signal_multiplier", 2}, {"nmea_ignore_valid_char", 1}, {"udp_port_lidar", 0}});
  EXPECT_THAT(lidartwin::config_errors(config, {}, body), testing::IsEmpty());
}

TEST(ConfigRules, ChoicesAreListedQuoted) {
  auto config = lidartwin::default_config_params();
  config["udp_profile_imu"] = "FAST";
  EXPECT_THAT(lidartwin::config_errors(config, {}, {"POST sensor/config", ""}),
              testing::ElementsAre(R"(POST sensor/config: /udp_profile_imu: must be one of "LEGACY", )"
                                   R"("ACCEL32_GYRO32_NMEA", "OFF", got a string "FAST")"));
}

}  // namespace
