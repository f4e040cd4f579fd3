// Live poses over HTTP (include/lidartwin/rig/pose_api.h).
#include "lidartwin/rig/pose_api.h"

#include "lidartwin/json/json_reader.h"

namespace lidartwin {
namespace {

using nlohmann::json;
namespace jr = json_reader;

// Any JSON number: finiteness is the message's own check (and counted as such), not a type error.
std::vector<double> read_vector(const jr::ObjectReader& object, std::string_view key, size_t count) {
  const json& value = object.at(key, "an array of " + std::to_string(count) + " numbers");
  const jr::Location at = object.child(key);
  if (!value.is_array() || value.size() != count)
    at.fail_expected("an array of " + std::to_string(count) + " numbers", value);
  std::vector<double> numbers;
  for (size_t i = 0; i < count; ++i) {
    if (!value[i].is_number()) at.child(i).fail_expected("a number", value[i]);
    numbers.push_back(value[i].get<double>());
  }
  return numbers;
}

std::optional<Eigen::Vector3d> read_optional_vector(const jr::ObjectReader& object, std::string_view key) {
  if (!object.find(key)) return std::nullopt;
  const auto v = read_vector(object, key, 3);
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

json vector_json(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

json message_json(const PoseMessage& m) {
  const Eigen::Quaterniond& q = m.pose.rotation;
  json out{{"sequence", m.sequence},
           {"time_ns", m.time_ns},
           {"position", vector_json(m.pose.translation)},
           {"orientation", json::array({q.x(), q.y(), q.z(), q.w()})}};
  if (m.velocity) out["velocity"] = vector_json(*m.velocity);
  if (m.angular_rate) out["angular_rate"] = vector_json(*m.angular_rate);
  return out;
}

}  // namespace

PoseMessage pose_message_from_json(const std::string& body, const std::string& source) {
  const json document = json::parse(body, nullptr, false);
  if (document.is_discarded()) throw PoseRejected(PoseRejection::kMalformed, source + ": the body is not JSON");
  PoseMessage message;
  Eigen::Vector4d q;
  try {
    const jr::ObjectReader object(document, {source, ""},
                                  {"sequence", "time_ns", "position", "orientation", "velocity", "angular_rate"},
                                  jr::UnknownKeys::kReject, "a pose");
    message.sequence = static_cast<uint32_t>(
        jr::read_integer(object.at("sequence", "an integer"), object.child("sequence"), 0, UINT32_MAX));
    message.time_ns =
        jr::read_integer(object.at("time_ns", "an integer"), object.child("time_ns"), INT64_MIN, INT64_MAX);
    const auto p = read_vector(object, "position", 3);
    message.pose.translation = {p[0], p[1], p[2]};
    const auto o = read_vector(object, "orientation", 4);
    q = {o[0], o[1], o[2], o[3]};
    message.velocity = read_optional_vector(object, "velocity");
    message.angular_rate = read_optional_vector(object, "angular_rate");
  } catch (const PoseRejected&) {
    throw;
  } catch (const InputError& e) {
    throw PoseRejected(PoseRejection::kMalformed, e.what());
  }
  validate_pose_message(message, q, source + " (pose " + std::to_string(message.sequence) + ")");
  return message;
}

json live_pose_status(const LivePoses& poses, const StreamStats& stream, int64_t now_steady_ns) {
  const LivePoseStats stats = poses.stats();
  const LivePoseOptions& options = poses.options();
  json rejected = json::object();
  for (size_t i = 0; i < stats.rejected.size(); ++i)
    rejected[to_string(static_cast<PoseRejection>(i))] = stats.rejected[i];
  json out{{"accepted", stats.accepted},
           {"rejected", rejected},
           {"rejected_total", stats.rejected_total()},
           {"lost", stats.lost},
           {"clock", to_string(options.clock)},
           {"clock_offset_ns", stats.clock_offset_ns},
           {"max_extrapolation_s", options.max_extrapolation_s},
           {"timeout", to_string(options.timeout)},
           {"newest", nullptr},
           {"stalled", true},
           {"columns_without_pose", stream.columns_without_pose},
           {"withheld_packets", stream.withheld_packets},
           {"recast_packets", stream.recast_packets},
           {"latency",
            {{"count", stream.pose_latency_count},
             {"p50_us", stream.pose_latency_p50_us},
             {"p99_us", stream.pose_latency_p99_us},
             {"max_us", stream.pose_latency_max_us}}}};
  if (stats.newest) {
    const double age_s = static_cast<double>(now_steady_ns - stats.newest_arrival_steady_ns) * 1e-9;
    out["newest"] = message_json(*stats.newest);
    out["newest_age_s"] = age_s;
    out["stalled"] = age_s > options.max_extrapolation_s;
  }
  return out;
}

ApiResponse live_pose_endpoint(LivePoses& poses, const StreamStats& stream, const ApiRequest& request) {
  const std::string path = origin_form_path(request.path);
  std::string_view resource(path);
  resource.remove_prefix(kExtensionPrefix.size());
  while (resource.ends_with('/')) resource.remove_suffix(1);
  if (resource != "pose") throw HttpError(404, "unknown endpoint " + path + ": lidartwin answers /lidartwin/v1/pose");
  if (request.method == "GET" || request.method == "HEAD") {
    return {200, live_pose_status(poses, stream, host_steady_ns()).dump(), {}};
  }
  if (request.method != "POST") {
    return {405,
            json{{"error", "method " + request.method + " is not allowed on " + path + "; allowed: GET, POST"}}.dump(),
            {{"Allow", "GET, POST"}}};
  }
  const int64_t arrival = host_steady_ns();
  try {
    const PoseMessage message = pose_message_from_json(request.body, "POST " + path);
    poses.receive(message, arrival);
    return {200, json{{"accepted", true}, {"sequence", message.sequence}}.dump(), {}};
  } catch (const PoseRejected& e) {
    if (e.reason() != PoseRejection::kTimeBackwards) poses.count_rejection(e.reason());  // receive() counted that one
    return {400, json{{"error", e.what()}, {"rejected", to_string(e.reason())}}.dump(), {}};
  }
}

}  // namespace lidartwin
