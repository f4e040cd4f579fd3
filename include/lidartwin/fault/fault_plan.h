#pragma once
// Faults a user injects to see whether their driver survives what real networks and sensors do
// (docs/fault-injection.md): packets lost, reordered, duplicated, delayed, cut short or with a bad
// CRC on the way; frame_id jumps; the sensor resetting, going to STANDBY or to ERROR; the HTTP API
// answering 500 or slowly. A plan is a value with one vocabulary: `serve --fault SPEC` and
// PUT /lidartwin/v1/faults take the same keys, and a plan is validated whole before it applies.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace lidartwin {

struct FaultPlan {
  // Every fault is a pure function of (seed, what it hits, that thing's sequence number), so the
  // same plan replays the same faults on the same packets whatever the host's timing.
  uint64_t seed = 0;

  // Datagrams on the way to the client (lidar and IMU, each stream on its own):
  double loss = 0.0;        // fraction of datagrams lost, in bursts of loss_burst consecutive ones
  int loss_burst = 1;       //
  double reorder = 0.0;     // fraction sent after the datagram that follows them
  double duplicate = 0.0;   // fraction sent twice in a row
  double truncate = 0.0;    // fraction cut to a shorter length (a client's size check drops them)
  double bad_crc = 0.0;     // lidar packets whose CRC footer is wrong (profiles with a CRC only)
  double delay_ms = 0.0;    // every datagram this much later...
  double jitter_ms = 0.0;   // ...plus a uniform [0, jitter_ms) each: jitter reorders as a network does
  double frame_jump = 0.0;  // per frame: the probability that frame_id jumps ahead from it on
  int frame_jump_by = 100;  // by this many

  // The sensor, at a time counted in seconds of streaming since the plan took effect (rounded to a
  // frame, so that a replay hits the same frame). Each happens once per plan.
  std::optional<double> reset_at;    // a reset, as after a power cycle: new init_id, stream restarts
  std::optional<double> standby_at;  // STANDBY for standby_for s: no packets, then a new init_id
  double standby_for = 1.0;
  std::optional<double> error_at;  // ERROR for error_for s, with an active alert; then a reset
  double error_for = 1.0;

  // The sensor's HTTP API (below /api/v1/; lidartwin's own endpoints are never faulted):
  double http_500 = 0.0;       // fraction of requests answered 500
  double http_delay_ms = 0.0;  // every answer this much later

  bool empty() const;  // nothing is injected
  bool has_packet_faults() const;
  bool has_sensor_events() const;
  friend bool operator==(const FaultPlan&, const FaultPlan&) = default;
};

// "loss=0.01,loss_burst=3,reorder=0.005,reset_at=10,seed=7" (keys as in the JSON form; "" = none).
// seed defaults to default_seed. Throws InputError naming the spec, the key and the problem.
FaultPlan fault_plan_from_spec(std::string_view spec, uint64_t default_seed);
// A JSON object of the same keys; source names the input in messages ("PUT /lidartwin/v1/faults").
FaultPlan fault_plan_from_json(const nlohmann::json& document, const std::string& source, uint64_t default_seed);
nlohmann::json to_json(const FaultPlan& plan);  // only what is set, and the seed
std::string to_spec(const FaultPlan& plan);     // the --fault SPEC that replays it

}  // namespace lidartwin
