// Fault injection for users (docs/fault-injection.md), against the real `lidartwin serve` and a
// client that configures it with the SDK's call sequence and reads its UDP stream: what the client
// sees is exactly what the daemon's fault log says it did, datagram by datagram, and the sensor's
// own faults (reset, ERROR, STANDBY) and the HTTP faults look to a client as a real sensor's do.
#include <chrono>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "e2e/support/batcher.h"
#include "e2e/support/daemon.h"
#include "e2e/support/room.h"  // Eigen, before httplib: <resolv.h> defines _res, a name Eigen uses
#include "e2e/support/sdk_client.h"
#include "e2e/support/udp_socket.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin::e2e::fault_injection_test {
namespace {

using Clock = std::chrono::steady_clock;

// A lidar packet as the client identifies it.
struct PacketId {
  uint32_t init_id = 0;
  uint32_t frame_id = 0;
  int measurement_id = 0;  // of its first column
  auto operator<=>(const PacketId&) const = default;
};

std::ostream& operator<<(std::ostream& out, const PacketId& id) {
  return out << "{init_id " << id.init_id << ", frame_id " << id.frame_id << ", m " << id.measurement_id << "}";
}

// Every lidar datagram the client received, in arrival order, and what did not decode.
struct Received {
  std::vector<PacketId> packets;
  std::vector<bool> crc_ok;
  size_t wrong_size = 0;
};

class FaultApi {
 public:
  explicit FaultApi(const Daemon& daemon) : client_(daemon.address(), daemon.http_port()) {
    client_.set_read_timeout(5);
  }
  json get(uint64_t since = 0) {
    auto result = client_.Get("/lidartwin/v1/faults?limit=100000&since=" + std::to_string(since));
    if (!result || result->status != 200) throw std::runtime_error("GET /lidartwin/v1/faults failed");
    return json::parse(result->body);
  }
  // The status of a PUT (or DELETE): -1 when no answer came.
  int put(const json& plan) { return status(client_.Put("/lidartwin/v1/faults", plan.dump(), "application/json")); }
  int clear() { return status(client_.Delete("/lidartwin/v1/faults")); }
  httplib::Result put_raw(const json& plan) {
    return client_.Put("/lidartwin/v1/faults", plan.dump(), "application/json");
  }

 private:
  static int status(const httplib::Result& result) {
    if (!result) ADD_FAILURE() << "no answer: " << httplib::to_string(result.error());
    return result ? result->status : -1;
  }

 public:
 private:
  httplib::Client client_;
};

// Reads lidar datagrams until `until` (or, with stop_when_quiet, until none came for 300 ms).
void receive(UdpSocket& socket, const PacketFormat& format, Received& out, Clock::time_point until) {
  Scan probe(format.format());
  while (Clock::now() < until) {
    auto datagram = socket.receive(std::chrono::milliseconds(100));
    if (!datagram) continue;
    if (datagram->bytes.size() != format.lidar_packet_size()) {
      ++out.wrong_size;
      continue;
    }
    std::string error;
    const auto decoded = format.decode(datagram->bytes, probe, &error);
    ASSERT_TRUE(decoded) << error;
    out.packets.push_back({decoded->header.init_id, decoded->header.frame_id, decoded->first_measurement_id});
    out.crc_ok.push_back(decoded->crc_ok);
  }
}

// Stops the stream the way a client would (operating_mode STANDBY), so that whatever the daemon
// still held back arrives, and reads until the socket is quiet.
void stop_stream_and_drain(SensorHttp& http, UdpSocket& socket, const PacketFormat& format, Received& out) {
  http.post("sensor/config?staging=true&reinit=true&persist=false", {{"operating_mode", "STANDBY"}});
  receive(socket, format, out, Clock::now() + std::chrono::milliseconds(600));
}

// The packets a session sends from frame 0, in order: frame_id f, columns 0, 16, 32, ...
std::vector<PacketId> natural_order(uint32_t init_id, uint32_t last_frame_id, int columns_per_packet,
                                    int packets_per_frame) {
  std::vector<PacketId> ids;
  for (uint32_t f = 0; f <= last_frame_id; ++f) {
    for (int p = 0; p < packets_per_frame; ++p) ids.push_back({init_id, f, p * columns_per_packet});
  }
  return ids;
}

PacketId id_of(const json& event) {
  return {event.at("init_id").get<uint32_t>(), event.at("frame_id").get<uint32_t>(),
          event.at("measurement_id").get<int>()};
}

// A client configured by the SDK-0.16 call sequence (init_client) with ports of its own.
struct Client {
  UdpSocket lidar;
  UdpSocket imu;
  SensorHttp http;
  Metadata metadata;
  explicit Client(const Daemon& daemon) : http(daemon.address(), daemon.http_port()) {
    ConfigRequest request;
    request.lidar_port = lidar.port();
    request.imu_port = imu.port();
    metadata = parse(sdk016_init_client(http, request));
  }
};

// The acceptance case of issue 27: 1 % loss (in bursts of 2), 1 % reordering and a reset in the
// middle of the stream, from `serve --fault`. Every packet the session sent from its frame 0 on
// reached the client, in order, except exactly the ones the log lists as lost; exactly the ones it
// lists as reordered arrived after the packet that followed them; the init_id changed after the
// frame the reset event names, and the new session starts at frame_id 0 with the init_id the
// metadata now serves.
TEST(FaultInjection, AnSdkClientSeesExactlyTheLossReorderingAndResetTheLogLists) {
  Daemon daemon("127.0.0.1", 0, [] {
    auto args = room_args();
    args.insert(args.end(), {"--fault", "loss=0.01,loss_burst=2,reorder=0.01", "--fault", "reset_at=4,seed=11"});
    return args;
  }());
  Client client(daemon);
  const PacketFormat format(client.metadata.format);
  const uint32_t first_init_id = client.metadata.sensor_info.initialization_id;
  Received received;
  receive(client.lidar, format, received, Clock::now() + std::chrono::milliseconds(6500));
  const json after = client.http.get_json("sensor/metadata/sensor_info");
  stop_stream_and_drain(client.http, client.lidar, format, received);

  const json log = FaultApi(daemon).get();
  const json& events = log.at("events");
  std::optional<json> reset;
  std::set<PacketId> lost, reordered;
  for (const json& event : events) {
    const std::string kind = event.at("kind");
    if (kind == "reset") reset = event;
    if (event.value("stream", "") != "lidar") continue;
    if (kind == "loss") lost.insert(id_of(event));
    if (kind == "reorder") reordered.insert(id_of(event));
  }
  ASSERT_TRUE(reset) << "no reset in the log: " << log.dump();
  ASSERT_EQ(reset->at("init_id"), first_init_id) << "the reset came before the client's session started";
  const uint32_t second_init_id = after.at("initialization_id");
  ASSERT_NE(second_init_id, first_init_id);

  // What the client must have seen: each session's packets in order, from its frame 0 to the
  // reset's last frame (the first session) or the last packet received (the second), less the
  // lost ones, each reordered one moved behind the next.
  const int cpp = client.metadata.format.columns_per_packet;
  const int per_frame = client.metadata.format.columns_per_frame / cpp;
  std::vector<PacketId> expected = natural_order(first_init_id, reset->at("last_frame_id"), cpp, per_frame);
  PacketId last_second{second_init_id, 0, 0};
  for (const PacketId& id : received.packets) {
    if (id.init_id == second_init_id) last_second = std::max(last_second, id);
  }
  for (const PacketId& id : natural_order(second_init_id, last_second.frame_id, cpp, per_frame)) {
    if (id <= last_second) expected.push_back(id);
  }
  std::erase_if(expected, [&](const PacketId& id) { return lost.contains(id); });
  for (size_t i = 0; i + 1 < expected.size(); ++i) {
    if (reordered.contains(expected[i]) && expected[i].init_id == expected[i + 1].init_id) {
      std::swap(expected[i], expected[i + 1]);
      ++i;  // the one that overtook it is sent normally
    }
  }

  EXPECT_GT(lost.size(), 10u) << "about 1 % of ~4,000 packets";
  EXPECT_GT(reordered.size(), 10u);
  EXPECT_EQ(received.wrong_size, 0u);
  ASSERT_EQ(received.packets.size(), expected.size());
  size_t mismatches = 0;
  for (size_t i = 0; i < expected.size() && mismatches < 10; ++i) {
    if (received.packets[i] != expected[i]) {
      ++mismatches;
      ADD_FAILURE() << "arrival " << i << ": got " << received.packets[i] << ", the log implies " << expected[i];
    }
  }
  EXPECT_EQ(log.at("counts").at("reset"), 1);
}

// bad CRCs, truncation, duplicates and frame_id jumps, set at run time: the client counts exactly
// as many of each as the log lists, and frame_id moves on by frame_jump_by at each logged jump.
TEST(FaultInjection, CorruptedDuplicatedAndJumpedPacketsReachTheClientAsLogged) {
  Daemon daemon("127.0.0.1", 0, room_args());
  Client client(daemon);
  FaultApi faults(daemon);
  ASSERT_EQ(faults.put({{"bad_crc", 0.02},
                        {"truncate", 0.02},
                        {"duplicate", 0.02},
                        {"frame_jump", 0.1},
                        {"frame_jump_by", 50},
                        {"seed", 3}}),
            200);
  const PacketFormat format(client.metadata.format);
  ASSERT_TRUE(format.has_crc());
  Received received;
  receive(client.lidar, format, received, Clock::now() + std::chrono::seconds(3));
  stop_stream_and_drain(client.http, client.lidar, format, received);
  const json log = faults.get();

  std::map<std::string, size_t> logged;
  std::vector<json> jumps;
  for (const json& event : log.at("events")) {
    if (event.value("stream", "") != "lidar") continue;
    ++logged[event.at("kind")];
    if (event.at("kind") == "frame_jump") jumps.push_back(event);
  }
  size_t bad_crc = 0, duplicates = 0, frame_id_jumps = 0;
  for (size_t i = 0; i < received.packets.size(); ++i) {
    bad_crc += received.crc_ok[i] ? 0 : 1;
    if (i == 0) continue;
    const PacketId& a = received.packets[i - 1];
    const PacketId& b = received.packets[i];
    duplicates += a == b ? 1 : 0;
    if (b.frame_id != a.frame_id && b.frame_id != a.frame_id + 1) {
      EXPECT_EQ(b.frame_id, a.frame_id + 1 + 50) << "a jump moves frame_id on by frame_jump_by";
      ++frame_id_jumps;
    }
  }
  EXPECT_GT(logged["bad_crc"], 5u);
  EXPECT_EQ(bad_crc, logged["bad_crc"]);
  EXPECT_EQ(received.wrong_size, logged["truncate"]);
  EXPECT_EQ(duplicates, logged["duplicate"]);
  EXPECT_EQ(frame_id_jumps, jumps.size());
  EXPECT_GT(jumps.size(), 0u);
}

// error_at: sensor_info says ERROR and sensor/alerts lists one active alert while nothing is sent;
// error_for later the sensor restarts with a new init_id and the alert is in the log, inactive.
// standby_at: STANDBY until a client asks for NORMAL again, as on a real sensor.
TEST(FaultInjection, ErrorAndStandbyLookToAClientAsARealSensorsDo) {
  Daemon daemon("127.0.0.1", 0, room_args());
  Client client(daemon);
  FaultApi faults(daemon);
  const auto status = [&] {
    return client.http.get_json("sensor/metadata/sensor_info").at("status").get<std::string>();
  };
  const auto wait_for = [&](const std::string& wanted, std::chrono::milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (status() != wanted && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    return status() == wanted;
  };
  ASSERT_EQ(faults.put({{"error_at", 0.3}, {"error_for", 1.5}}), 200);
  ASSERT_TRUE(wait_for("ERROR", std::chrono::seconds(3)));
  const json alerts = client.http.get_json("sensor/alerts");
  ASSERT_EQ(alerts.at("active").size(), 1u) << alerts.dump();
  EXPECT_EQ(alerts["active"][0]["level"], "ERROR");
  EXPECT_EQ(alerts["active"][0]["active"], true);
  client.lidar.drain();
  EXPECT_FALSE(client.lidar.receive(std::chrono::milliseconds(500))) << "a sensor in ERROR sends nothing";
  ASSERT_TRUE(wait_for("RUNNING", std::chrono::seconds(3)));
  const json info = client.http.get_json("sensor/metadata/sensor_info");
  EXPECT_NE(info.at("initialization_id"), client.metadata.sensor_info.initialization_id);
  const json cleared = client.http.get_json("sensor/alerts");
  EXPECT_EQ(cleared.at("active").size(), 0u);
  ASSERT_EQ(cleared.at("log").size(), 2u);
  EXPECT_EQ(cleared["log"][1]["active"], false);
  const PacketFormat format(client.metadata.format);
  Received after;
  receive(client.lidar, format, after, Clock::now() + std::chrono::milliseconds(500));
  ASSERT_FALSE(after.packets.empty()) << "streaming again after the restart";
  EXPECT_EQ(after.packets.back().init_id, info.at("initialization_id"));

  ASSERT_EQ(faults.put({{"standby_at", 0.2}, {"standby_for", 60}}), 200);
  ASSERT_TRUE(wait_for("STANDBY", std::chrono::seconds(3)));
  client.http.post("sensor/config?staging=true&reinit=true&persist=false", {{"operating_mode", "NORMAL"}});
  EXPECT_EQ(status(), "RUNNING") << "a client's reinit with operating_mode NORMAL ends STANDBY";
  EXPECT_EQ(faults.get().at("counts").at("standby"), 1);
}

// http_500 answers the sensor's API with 500 (never lidartwin's own endpoints, so the plan can be
// changed back); http_delay_ms answers late; a bad plan is refused whole and the old one stays.
TEST(FaultInjection, TheHttpApiFailsOrAnswersLateAsPlannedAndABadPlanChangesNothing) {
  Daemon daemon("127.0.0.1", 0, room_args());
  SensorHttp http(daemon.address(), daemon.http_port());
  FaultApi faults(daemon);
  ASSERT_EQ(faults.put({{"http_500", 1}}), 200);
  const auto failed = http.raw_get("/api/v1/sensor/metadata/sensor_info");
  ASSERT_TRUE(failed) << httplib::to_string(failed.error());
  EXPECT_EQ(failed->status, 500);
  EXPECT_NE(failed->body.find("injected"), std::string::npos) << failed->body;
  EXPECT_EQ(faults.get().at("counts").at("http_500"), 1);

  const auto refused = faults.put_raw({{"http_500", 0}, {"loss", "lots"}});
  ASSERT_TRUE(refused) << httplib::to_string(refused.error());
  EXPECT_EQ(refused->status, 400);
  EXPECT_NE(refused->body.find("/loss"), std::string::npos) << refused->body;
  EXPECT_EQ(faults.get().at("plan").at("http_500"), 1.0) << "a refused plan leaves the old one";

  ASSERT_EQ(faults.put({{"http_delay_ms", 300}}), 200);
  const auto start = Clock::now();
  const auto late = http.raw_get("/api/v1/sensor/metadata/sensor_info");
  ASSERT_TRUE(late) << httplib::to_string(late.error());
  EXPECT_EQ(late->status, 200);
  EXPECT_GE(Clock::now() - start, std::chrono::milliseconds(300));
  ASSERT_EQ(faults.clear(), 200);
  EXPECT_EQ(faults.get().at("spec"), "seed=0");
}

TEST(FaultInjection, ABadFaultFlagIsRefusedNamingItsKey) {
  const auto [code, output] = run_cli("serve --http-port 0 --fault loss=0.01,reorder=often");
  EXPECT_EQ(code, 2);
  EXPECT_NE(output.find("--fault \"loss=0.01,reorder=often\": /reorder: must be a number"), std::string::npos)
      << output;
}

}  // namespace
}  // namespace lidartwin::e2e::fault_injection_test
