#pragma once
// Live poses over HTTP (docs/live-poses.md): POST /lidartwin/v1/pose takes one pose as JSON, the
// same fields as the UDP message; GET /lidartwin/v1/pose reports the stream's health.
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "lidartwin/http_api/request_handler.h"
#include "lidartwin/pose/live_poses.h"
#include "lidartwin/sensor/stream_config.h"

namespace lidartwin {

// {"sequence": 17, "time_ns": 1234, "position": [x, y, z], "orientation": [qx, qy, qz, qw],
//  "velocity": [vx, vy, vz], "angular_rate": [wx, wy, wz]} (the last two optional). Throws
// PoseRejected naming `source`, the field and the problem.
PoseMessage pose_message_from_json(const std::string& body, const std::string& source);

// What GET reports: counters, the newest pose and its age, the clock mapping, the policies, and
// what the streamer saw (columns without a pose, withheld packets, pose-to-packet latency).
nlohmann::json live_pose_status(const LivePoses& poses, const StreamStats& stream, int64_t now_steady_ns);

// The endpoint under /lidartwin/v1/: "pose" (GET, POST); anything else is a 404.
ApiResponse live_pose_endpoint(LivePoses& poses, const StreamStats& stream, const ApiRequest& request);

}  // namespace lidartwin
