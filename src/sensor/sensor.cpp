// The sensor state machine (protocol doc 2.7).
#include "lidartwin/sensor/sensor.h"

#include <algorithm>
#include <utility>

#include "lidartwin/error.h"
#include "lidartwin/json/json_reader.h"
#include "sensor/activation.h"
#include "sensor/state_file.h"

namespace lidartwin {
namespace {

using nlohmann::json;

constexpr const char* kDestinationKeys[] = {"udp_dest", "udp_dest_zm", "udp_ip"};

// The destinations a client wrote, resolved now: "@auto" is only meaningful at write time.
json resolve_destinations(const json& partial, const std::string& peer_ip, const json_reader::Location& at) {
  json resolved = partial;
  for (const char* key : kDestinationKeys) {
    if (partial.contains(key)) resolved[key] = resolve_udp_dest(partial[key], at.child(key), peer_ip);
  }
  return resolved;
}

// Keys overwrite; nothing is deleted (a null value is a value and fails validation).
json merged(json config, const json& partial) {
  for (const auto& [key, value] : partial.items()) config[key] = value;
  // FW 2.0/2.1 called udp_dest udp_ip; keep both names on one value (protocol doc 2.7).
  if (partial.contains("udp_dest") && config.contains("udp_ip")) {
    config["udp_ip"] = config["udp_dest"];
  } else if (partial.contains("udp_ip")) {
    config["udp_dest"] = config["udp_ip"];
  }
  return config;
}

json checked_object(const json& partial, const json_reader::Location& at) {
  if (!partial.is_object()) at.fail_expected("a JSON object of config keys", partial);
  return partial;
}

}  // namespace

std::string_view to_string(UserDataPolicy policy) {
  return policy == UserDataPolicy::kKeepOnConfigDelete ? "keep_on_config_delete" : "clear_on_config_delete";
}

std::optional<UserDataPolicy> user_data_policy_from_string(std::string_view text) {
  if (text == "keep_on_config_delete") return UserDataPolicy::kKeepOnConfigDelete;
  if (text == "clear_on_config_delete") return UserDataPolicy::kClearOnConfigDelete;
  return std::nullopt;
}

std::optional<int64_t> Sensor::packets_clock_ns() const {
  return options_.packets_clock_ns ? options_.packets_clock_ns() : std::nullopt;
}

Sensor::Sensor(SensorIdentity identity, SensorOptions options)
    : identity_(std::move(identity)),
      options_(std::move(options)),
      time_(options_.time ? options_.time : std::make_shared<const TimeBase>(TimeBase::from_host())) {
  parse_prod_sn(identity_.prod_sn);  // throws early, naming the identity's bad serial
  // Start-up order: firmware defaults, then what was persisted, then the caller's overrides.
  saved_ = default_config_params();
  if (!options_.state_file.empty()) {
    if (auto state = load_state(options_.state_file)) {
      saved_ = merged(saved_, state->config);
      user_data_ = state->user_data;
    }
    // The defaults are valid, so what is wrong came from the file's "config" object.
    validate_config(saved_, identity_.limits, {options_.state_file.string(), "/config"});
  }
  const json_reader::Location overrides_at{"config overrides", ""};
  const json overrides = checked_object(options_.config_overrides, overrides_at);
  json initial = merged(saved_, resolve_destinations(overrides, "", overrides_at));
  validate_config(initial, identity_.limits, overrides_at);
  std::lock_guard lock(mutex_);
  activate_locked(initial);
}

Sensor::~Sensor() = default;

void Sensor::activate_locked(const json& config) {
  const uint32_t previous_id = stream_ ? stream_->init_id : 0;
  const uint64_t generation = stream_ ? stream_->generation + 1 : 1;
  Activation activation = activate(identity_, config, next_init_id(previous_id), generation);
  active_ = std::move(activation.config);
  staged_ = active_;  // staged is a copy of active after each reinit (protocol doc 2.7)
  metadata_json_ = std::move(activation.metadata_json);
  stream_ = std::move(activation.stream);
  initializing_until_ = std::chrono::steady_clock::now() + options_.initializing_time;
}

std::string Sensor::status_locked() const {
  if (!fault_status_.empty()) return fault_status_;
  if (std::chrono::steady_clock::now() < initializing_until_) return "INITIALIZING";
  return stream_->streaming ? "RUNNING" : "STANDBY";
}

std::string Sensor::status() const {
  std::lock_guard lock(mutex_);
  return status_locked();
}

json Sensor::sensor_info() const {
  std::lock_guard lock(mutex_);
  json info = metadata_json_.at("sensor_info");
  info["status"] = status_locked();
  return info;
}

json Sensor::metadata() const {
  std::lock_guard lock(mutex_);
  json document = metadata_json_;
  document["sensor_info"]["status"] = status_locked();
  return document;
}

std::string Sensor::metadata_text() const {
  std::lock_guard lock(mutex_);
  const std::string status = status_locked();
  if (metadata_text_.empty() || metadata_text_generation_ != stream_->generation || metadata_text_status_ != status) {
    json document = metadata_json_;
    document["sensor_info"]["status"] = status;
    metadata_text_ = document.dump(-1, ' ', false, json::error_handler_t::replace);
    metadata_text_generation_ = stream_->generation;
    metadata_text_status_ = status;
  }
  return metadata_text_;
}

std::optional<json> Sensor::metadata_section(std::string_view name) const {
  if (name == "sensor_info") return sensor_info();
  std::lock_guard lock(mutex_);
  const auto it = metadata_json_.find(name);
  if (it == metadata_json_.end()) return std::nullopt;
  return *it;
}

json Sensor::active_config() const {
  std::lock_guard lock(mutex_);
  return active_;
}

TimestampMode Sensor::timestamp_mode() const {
  std::lock_guard lock(mutex_);
  // Validated on the way in (config_rules), so one of the three.
  return timestamp_mode_from_string(stream_->timestamp_mode).value_or(TimestampMode::kInternalOsc);
}

json Sensor::staged_config() const {
  std::lock_guard lock(mutex_);
  return staged_;
}

void Sensor::write_staged(const json& partial, const std::string& peer_ip, const std::string& source) {
  const json_reader::Location at{source, ""};
  // Name resolution may block: do it before taking the lock.
  const json resolved = resolve_destinations(checked_object(partial, at), peer_ip, at);
  std::lock_guard lock(mutex_);
  json candidate = merged(staged_, resolved);
  validate_config(candidate, identity_.limits, at);
  // The whole result must also describe a stream, so a later reinit cannot fail.
  make_metadata(sensor_info_of(identity_, stream_->init_id), identity_.beams, candidate);
  staged_ = std::move(candidate);
}

void Sensor::reinit() {
  std::lock_guard notify_lock(notify_mutex_);
  StreamConfigPtr stream;
  {
    std::lock_guard lock(mutex_);
    if (fault_status_ == "STANDBY") fault_status_.clear();
    activate_locked(staged_);
    hold_stream_locked();
    stream = stream_;
  }
  if (options_.on_client) options_.on_client(ClientEvent::kReinit);
  notify(stream);
}

void Sensor::metadata_read() const {
  if (options_.on_client) options_.on_client(ClientEvent::kMetadataRead);
}

void Sensor::hold_stream_locked() {
  if (fault_status_.empty() || !stream_->streaming) return;
  auto held = std::make_shared<StreamConfig>(*stream_);
  held->streaming = false;
  ++held->generation;
  stream_ = std::move(held);
}

void Sensor::restart() {
  std::lock_guard notify_lock(notify_mutex_);
  StreamConfigPtr stream;
  {
    std::lock_guard lock(mutex_);
    const json staged = staged_;
    activate_locked(active_);
    staged_ = staged;  // a reset keeps what was staged and not applied, as flash would
    hold_stream_locked();
    stream = stream_;
  }
  notify(stream);
}

void Sensor::enter_fault_state(const std::string& status, std::optional<SensorAlert> alert) {
  std::lock_guard notify_lock(notify_mutex_);
  StreamConfigPtr stream;
  {
    std::lock_guard lock(mutex_);
    fault_status_ = status;
    if (alert) {
      const auto realtime =
          std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch());
      active_alert_ =
          json{{"id", alert->id},   {"category", alert->category},       {"level", alert->level},
               {"msg", alert->msg}, {"msg_verbose", alert->msg_verbose}, {"realtime", std::to_string(realtime.count())},
               {"active", true},    {"cursor", next_alert_cursor_++}};
      alert_log_.push_back(*active_alert_);
    }
    hold_stream_locked();
    stream = stream_;
  }
  notify(stream);
}

void Sensor::leave_fault_state() {
  {
    std::lock_guard lock(mutex_);
    if (fault_status_.empty()) return;
    fault_status_.clear();
    if (active_alert_) {
      json cleared = *active_alert_;
      cleared["active"] = false;
      cleared["realtime"] = std::to_string(
          std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
              .count());
      cleared["cursor"] = next_alert_cursor_++;
      alert_log_.push_back(std::move(cleared));
      active_alert_.reset();
    }
  }
  restart();
}

json Sensor::alerts() const {
  std::lock_guard lock(mutex_);
  json active = json::array();
  if (active_alert_) active.push_back(*active_alert_);
  return {{"active", active}, {"log", alert_log_}, {"next_cursor", next_alert_cursor_}};
}

void Sensor::persist() {
  std::lock_guard lock(mutex_);
  saved_ = active_;
  save_state_locked();
}

void Sensor::save_state_locked() const {
  if (options_.state_file.empty()) return;
  save_state(options_.state_file, SavedState{saved_, user_data_});
}

UserData Sensor::user_data() const {
  std::lock_guard lock(mutex_);
  return user_data_;
}

void Sensor::set_user_data(std::string value, UserDataPolicy policy) {
  std::lock_guard lock(mutex_);
  user_data_ = UserData{std::move(value), policy};
  save_state_locked();  // a real sensor keeps user data in flash at once
}

void Sensor::delete_user_data() {
  std::lock_guard lock(mutex_);
  user_data_ = UserData{};
  save_state_locked();
}

Sensor::StreamConfigPtr Sensor::stream_config() const {
  std::lock_guard lock(mutex_);
  return stream_;
}

int Sensor::subscribe(Subscriber subscriber) {
  std::lock_guard notify_lock(notify_mutex_);
  subscriber(stream_config());
  subscribers_.emplace_back(next_subscriber_id_, std::move(subscriber));
  return next_subscriber_id_++;
}

void Sensor::unsubscribe(int id) {
  std::lock_guard notify_lock(notify_mutex_);
  std::erase_if(subscribers_, [id](const auto& entry) { return entry.first == id; });
}

// Called with notify_mutex_ held and mutex_ free.
void Sensor::notify(const StreamConfigPtr& config) {
  for (const auto& entry : subscribers_) entry.second(config);
}

void Sensor::set_stream_stats(const StreamStats& stats) {
  std::lock_guard lock(mutex_);
  stats_ = stats;
}

StreamStats Sensor::stream_stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace lidartwin
