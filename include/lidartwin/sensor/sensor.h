#pragma once
// The virtual sensor's state machine (protocol doc 2.7): active, staged and saved config, user
// data, status, initialization_id and the StreamConfig the streamer follows. Thread-safe: the
// HTTP server calls it from its thread pool while the streamer reads the stream config.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/metadata/metadata.h"
#include "lidartwin/profile/beam_intrinsics.h"
#include "lidartwin/sensor/config_rules.h"
#include "lidartwin/sensor/stream_config.h"
#include "lidartwin/sensor/time_base.h"

namespace lidartwin {

// Who the sensor says it is (sensor_info, protocol doc 2.5) and what it can do. FW 3.1 keeps the
// SDK on the REST config path and off the zone-monitor fetch (protocol doc 2.2).
struct SensorIdentity {
  std::string prod_line = "OS-1-64";
  std::string prod_pn = "840-102145-D";
  std::string prod_sn = "122201000123";  // decimal digits, at most 40 bits (packet header field)
  BeamIntrinsics beams;
  ConfigLimits limits;  // lidar modes and lidar profiles this product supports
  std::string image_rev = "ousteros-image-prod-bootes-v3.1.0+20240426041747";
  std::string build_rev = "v3.1.0";
  std::string build_date = "2024-04-26T02:34:31Z";
};

// What a client did that the daemon may wait for (serve --motion-start configured).
enum class ClientEvent {
  kReinit,        // a reinit activated the staged config (REST reinit=true, cmd reinitialize)
  kMetadataRead,  // GET sensor/metadata: what every client reads before it streams (protocol doc 2.4 (b))
};

struct SensorOptions {
  // Where persist() saves the config and user data; restored at start. Empty = RAM only.
  std::filesystem::path state_file;
  // Applied over the saved config at start (e.g. from CLI flags); not saved until persist().
  nlohmann::json config_overrides = nlohmann::json::object();
  // How long sensor_info reports "INITIALIZING" after a reinit. Clients poll every 1 s while it
  // does (protocol doc 2.4 (b)), so keep it short; 0 = never.
  std::chrono::milliseconds initializing_time{0};
  // The clocks the sensor reports its time on (time/sensor, telemetry), the ones its packets are
  // stamped on: a rig's sensors share one. Null: a time base of the sensor's own.
  std::shared_ptr<const TimeBase> time = nullptr;
  // Told of client events on the client's HTTP thread: kReinit after the config was activated and
  // before subscribers hear of it. Must be quick and must not call the sensor.
  std::function<void(ClientEvent)> on_client = nullptr;
  // When the packets carry a clock that is not the sensor's own (lock-step: the simulation's; with
  // --stamp-pose-clock: the poses'), what it reads now, in ns; nullopt until it is known.
  // GET time/sensor then reports it, whatever the timestamp_mode. Any thread.
  std::function<std::optional<int64_t>()> packets_clock_ns = nullptr;
};

// An entry of GET sensor/alerts (protocol doc 2.5: HIL tests read "active" and "log"; each entry
// has an id such as "0x01000015", a category, a level and messages).
struct SensorAlert {
  std::string id;
  std::string category;
  std::string level = "ERROR";
  std::string msg;
  std::string msg_verbose;
};

enum class UserDataPolicy { kKeepOnConfigDelete, kClearOnConfigDelete };
std::string_view to_string(UserDataPolicy policy);  // "keep_on_config_delete", ...
std::optional<UserDataPolicy> user_data_policy_from_string(std::string_view text);

struct UserData {
  std::string value;
  UserDataPolicy policy = UserDataPolicy::kClearOnConfigDelete;
};

class Sensor {
 public:
  using StreamConfigPtr = std::shared_ptr<const StreamConfig>;
  using Subscriber = std::function<void(const StreamConfigPtr&)>;

  // Starts from default_config_params(), then the state file (if it exists), then the overrides,
  // and activates that config. Throws InputError naming the state file or the override key when
  // either is invalid, or when the identity cannot describe a sensor.
  Sensor(SensorIdentity identity, SensorOptions options = {});
  Sensor(const Sensor&) = delete;
  Sensor& operator=(const Sensor&) = delete;
  ~Sensor();

  const SensorIdentity& identity() const { return identity_; }

  // Read side, as served over HTTP (protocol doc 2.3, 2.5, 3.1).
  nlohmann::json sensor_info() const;
  nlohmann::json metadata() const;  // nested document, all 7 sections + imu_data_format
  // metadata() as the JSON text the API serves, kept until the config or status changes: drivers
  // and dashboards poll it, and copying and printing the document was most of each request's CPU.
  std::string metadata_text() const;
  std::optional<nlohmann::json> metadata_section(std::string_view name) const;
  nlohmann::json active_config() const;
  nlohmann::json staged_config() const;
  std::string status() const;  // INITIALIZING, RUNNING or STANDBY

  // Merges `partial` (a JSON object) into the staged config. "@auto" and host names in
  // udp_dest/udp_dest_zm/udp_ip resolve now, against `peer_ip` (protocol doc 2.7). The resulting
  // config is validated as a whole: either it replaces staged entirely or InputError names every
  // bad key and staged is unchanged. `source` names the input in those messages, as a
  // json_reader::Location's source ("POST sensor/config": "POST sensor/config: /lidar_mode: ...").
  void write_staged(const nlohmann::json& partial, const std::string& peer_ip, const std::string& source = "config");
  // staged -> active, new initialization_id, generation + 1; subscribers are told.
  void reinit();
  // active -> saved, written to the state file (atomically) when there is one.
  void persist();
  // The HTTP API says a client read the metadata (tells SensorOptions::on_client).
  void metadata_read() const;

  // The sensor's own faults, as a user injects them (docs/fault-injection.md):
  // - restart(): as after a reset or power cycle, the active config streams again with a new
  //   initialization_id;
  // - enter_fault_state("STANDBY" or "ERROR", alert): that status, nothing streams, and the alert
  //   (if any) is active in sensor/alerts. A reinit in STANDBY leaves it (as operating_mode NORMAL
  //   would); ERROR stays until leave_fault_state(), which restarts and logs the alert inactive.
  void restart();
  void enter_fault_state(const std::string& status, std::optional<SensorAlert> alert);
  void leave_fault_state();
  nlohmann::json alerts() const;  // {"active": [...], "log": [...], "next_cursor": n}

  UserData user_data() const;
  void set_user_data(std::string value, UserDataPolicy policy);
  void delete_user_data();

  // The current stream config. subscribe() calls `subscriber` once with it at once and then after
  // every reinit, in generation order, never under the sensor's state lock (it may call the read
  // side; it must not call reinit(), subscribe() or unsubscribe()). Returns an id for
  // unsubscribe().
  StreamConfigPtr stream_config() const;
  int subscribe(Subscriber subscriber);
  void unsubscribe(int id);

  void set_stream_stats(const StreamStats& stats);
  StreamStats stream_stats() const;
  const TimeBase& time() const { return *time_; }
  // SensorOptions::packets_clock_ns: nullopt when the packets carry the sensor's own clocks.
  std::optional<int64_t> packets_clock_ns() const;
  // The active config's timestamp_mode (protocol doc 6.3): the clock the sensor's time reads.
  TimestampMode timestamp_mode() const;

 private:
  void activate_locked(const nlohmann::json& config);
  void hold_stream_locked();  // in a fault state: the stream config as activated, but not streaming
  void save_state_locked() const;
  std::string status_locked() const;
  void notify(const StreamConfigPtr& config);

  const SensorIdentity identity_;
  const SensorOptions options_;
  const std::shared_ptr<const TimeBase> time_;

  mutable std::mutex mutex_;  // guards everything below
  nlohmann::json active_;
  nlohmann::json staged_;
  nlohmann::json saved_;
  nlohmann::json metadata_json_;  // derived from active_ at the last reinit
  StreamConfigPtr stream_;
  UserData user_data_;
  std::chrono::steady_clock::time_point initializing_until_{};
  StreamStats stats_;
  std::string fault_status_;           // "" or the injected STANDBY / ERROR
  mutable std::string metadata_text_;  // metadata() printed, for metadata_text_status_
  mutable std::string metadata_text_status_;
  mutable uint64_t metadata_text_generation_ = 0;
  std::optional<nlohmann::json> active_alert_;
  std::vector<nlohmann::json> alert_log_;
  uint64_t next_alert_cursor_ = 0;

  // Held while subscribers run so that they see reinits in order; taken before mutex_.
  std::mutex notify_mutex_;
  std::vector<std::pair<int, Subscriber>> subscribers_;  // guarded by notify_mutex_
  int next_subscriber_id_ = 1;
};

}  // namespace lidartwin
