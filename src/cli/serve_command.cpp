// `lidartwin serve`: the daemon. A Sensor (state machine) behind the HTTP API, and a Streamer that
// follows the sensor's active config; Ctrl-C or SIGTERM stops both and exits 0.
#include <algorithm>
#include <condition_variable>
#include <csignal>
#include <mutex>
#include <stop_token>
#include <thread>
#include <iostream>

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>

#include <asio.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "cli/command.h"
#include "cli/format_validators.h"
#include "cli/serve_inputs.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/error.h"
#include "lidartwin/http_api/http_server.h"
#include "lidartwin/packet/data_format.h"
#include "lidartwin/scene/scene.h"
#include "lidartwin/streamer/streamer.h"

namespace lidartwin::cli {
namespace {

void setup_logging(const std::string& level) {
  auto logger = spdlog::stderr_color_mt("lidartwin");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  spdlog::set_level(spdlog::level::from_str(level));
}

// The bind error's remedies (protocol doc 2.1) as one line on stderr.
int report_bind_error(const BindError& error) {
  std::string message = error.what();
  std::replace(message.begin(), message.end(), '\n', ' ');
  std::cerr << "lidartwin: " << message << std::endl;
  return 2;
}

// Runs until SIGINT/SIGTERM: the signal stops the streamer, which leaves the io_context without
// work, so run() returns; then the HTTP server is stopped and the subscription dropped.
int run_daemon(asio::io_context& io, Sensor& sensor, HttpServer& http, Streamer& streamer) {
  // Stats go to the sensor from a thread of their own: the send clock must never wait for the
  // sensor's lock, which HTTP threads hold.
  std::jthread stats_pump([&sensor, &streamer](std::stop_token stop) {
    const sched_param normal{};
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);  // not the clock's SCHED_FIFO
    std::mutex mutex;
    std::condition_variable_any tick;
    std::unique_lock lock(mutex);
    while (!tick.wait_for(lock, stop, std::chrono::seconds(1), [] { return false; })) {
      if (stop.stop_requested()) break;
      sensor.set_stream_stats(streamer.stats());
    }
  });
  const int subscription = sensor.subscribe([&streamer](const Sensor::StreamConfigPtr& config) { streamer.apply(config); });
  asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&streamer](const asio::error_code& error, int signal_number) {
    if (error) return;
    spdlog::info("serve: {} received, stopping", signal_number == SIGINT ? "SIGINT" : "SIGTERM");
    streamer.stop();
  });
  // The send clock's wake-ups should not be rounded up by the default 50 us timer slack.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  io.run();
  stats_pump.request_stop();
  sensor.unsubscribe(subscription);
  http.stop();
  spdlog::info("serve: stopped");
  return 0;
}

// The send clock on a busy host (protocol doc 1 item 12): as SCHED_FIFO it preempts casting and
// everything else the moment a deadline comes. Needs root or CAP_SYS_NICE; without it, casting
// runs niced instead. The HTTP threads, started before, keep the normal policy.
bool raise_send_clock_priority() {
  sched_param param{};
  param.sched_priority = 10;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
}

Sensor make_sensor(const ServeFlags& flags, const SensorProfile& profile, const std::array<uint8_t, 4>& address) {
  SensorOptions options;
  options.state_file = flags.state_file;
  options.config_overrides = config_overrides(flags);
  try {
    return Sensor(make_identity(profile, address, flags.serial_number), options);
  } catch (const InputError& e) {
    throw InputError(std::string("--lidar-mode/--udp-profile/--state-file: ") + e.what());
  }
}

int serve(const ServeFlags& flags) {
  setup_logging(flags.log_level);
  const auto address = parse_address(flags.address);
  const SensorProfile profile = load_profile(flags.profile);
  EffectChain chain = EffectChain::from_json(profile.effects, "profile " + profile.name + ": /effects");
  const auto scene_file = scene_path(flags);
  Trajectory trajectory = load_trajectory(flags);
  const Scene scene = Scene::load(scene_file);
  spdlog::info("serve: {} ({}) in {} ({} triangles), trajectory of {:.1f} s", profile.prod_line, profile.name,
               scene_file.string(), scene.triangle_count(), trajectory.duration_s());
  Sensor sensor = make_sensor(flags, profile, address);

  HttpServerOptions http_options;
  http_options.address = flags.address;
  http_options.port = flags.http_port;
  HttpServer http(sensor, http_options);
  try {
    http.start();
  } catch (const BindError& e) {
    return report_bind_error(e);
  }
  spdlog::info("serve: sensor {} sn {} answering on http://{}:{}/api/v1/", sensor.identity().prod_line,
               sensor.identity().prod_sn, flags.address, http.port());

  asio::io_context io;
  StreamerOptions options;
  const bool realtime = raise_send_clock_priority();
  options.render_nice = realtime ? 0 : 5;
  spdlog::info("serve: send clock runs {}", realtime ? "SCHED_FIFO" : "at normal priority (no CAP_SYS_NICE), casting niced");
  options.source_address = address;
  options.render.seed = flags.seed;
  options.render.threads = flags.threads;
  options.record_dir = flags.record_dir;
  options.spin_us = flags.spin_us;
  Streamer streamer(io, scene, profile, std::move(chain), std::move(trajectory), options);
  return run_daemon(io, sensor, http, streamer);
}

void setup_serve(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<ServeFlags>();
  CLI::App* sub = app.add_subcommand("serve", "Run a virtual sensor: HTTP API and UDP lidar/IMU streams");
  sub->add_option("--profile", flags->profile, "sensor profile name or .json path")->capture_default_str();
  sub->add_option("--scene", flags->scene, "glTF scene (default scenes/plant.glb)");
  auto* trajectory = sub->add_option("--trajectory", flags->trajectory,
                                     "TUM trajectory (default scenes/plant_inspection.tum with the default scene)");
  sub->add_option("--pose", flags->pose, "a fixed pose \"x y z qx qy qz qw\"")->excludes(trajectory);
  sub->add_option("--address", flags->address, "the sensor's IPv4 address (HTTP and UDP source)")->capture_default_str();
  sub->add_option("--http-port", flags->http_port, "HTTP port (80 as on a real sensor; 0 = any)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  sub->add_option("--seed", flags->seed, "noise seed")->capture_default_str();
  sub->add_option("--serial-number", flags->serial_number,
                  "prod_sn, 1 to 12 digits (default 122201 + digits from --address; give each sensor of a "
                  "rig its own when they all bind 0.0.0.0)")
      ->check(serial_number_validator());
  sub->add_option("--record", flags->record_dir, "also write every sent packet to DIR/capture.pcap + DIR/metadata.json");
  sub->add_option("--lidar-mode", flags->lidar_mode, "initial lidar_mode, e.g. 1024x10")->check(lidar_mode_validator());
  sub->add_option("--udp-profile", flags->udp_profile, "initial udp_profile_lidar")->check(udp_profile_validator());
  sub->add_option("--state-file", flags->state_file, "where persisted config and user data live");
  sub->add_option("--threads", flags->threads, "ray casting threads (0 = all cores)")->check(CLI::Range(0, 1024));
  sub->add_option("--spin-us", flags->spin_us, "wake this early and spin to each packet's deadline (0 = sleep only)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  sub->add_option("--log-level", flags->log_level, "trace, debug, info, warn, error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  sub->callback([&run, flags] { run = [flags] { return serve(*flags); }; });
}

const RegisterCommand registered("serve", setup_serve);

}  // namespace
}  // namespace lidartwin::cli
