#pragma once
// The e2e tests' scene: small, closed and quick to cast.
#include <filesystem>
#include <string>
#include <vector>

#include "e2e/support/daemon.h"
#include "support/test_scene.h"

namespace lidartwin::e2e {

// The floor, ceiling and walls of an 8 x 6 x 3 m room.
inline std::vector<test::TestObject> room_shell() {
  using test::quad;
  const float x0 = -4, x1 = 4, y0 = -3, y1 = 3, z0 = 0, z1 = 3;
  return {
      quad("floor", {x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0}, 0.3f),
      quad("ceiling", {x0, y0, z1}, {x0, y1, z1}, {x1, y1, z1}, {x1, y0, z1}, 0.6f),
      quad("wall_north", {x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1}, 0.5f),
      quad("wall_south", {x0, y0, z0}, {x0, y0, z1}, {x1, y0, z1}, {x1, y0, z0}, 0.5f),
      quad("wall_east", {x1, y0, z0}, {x1, y0, z1}, {x1, y1, z1}, {x1, y1, z0}, 0.8f),
      quad("wall_west", {x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, {x0, y0, z1}, 0.2f),
  };
}

// A closed 8 x 6 x 3 m room with a pillar and a crate: every beam of a sensor standing inside
// hits something, and it casts in microseconds (the 2-core CI box runs several daemons at once).
inline std::filesystem::path room_scene() {
  const auto path = scratch_dir() / "room.glb";
  if (std::filesystem::exists(path)) return path;
  using Eigen::Vector3f;
  using test::quad;
  std::vector<test::TestObject> objects = room_shell();
  objects.push_back(test::box("pillar", {1.5f, 1.0f, 0.0f}, {1.9f, 1.4f, 3.0f}, 0.7f));
  objects.push_back(test::box("crate", {-2.0f, -1.5f, 0.0f}, {-1.2f, -0.7f, 0.8f}, 0.4f));
  test::write_glb(path, objects);
  return path;
}

// The same room with nothing in it: every point a sensor inside sees lies on one of six planes,
// x = +-4, y = +-3, z = 0 and z = 3.
inline std::filesystem::path empty_room_scene() {
  const auto path = scratch_dir() / "empty_room.glb";
  if (!std::filesystem::exists(path)) test::write_glb(path, room_shell());
  return path;
}

// The sensor 1.5 m above the room's floor, level.
inline constexpr const char* kRoomPose = "0 0 1.5 0 0 0 1";

// Flags for a quick sensor in the room: the caller adds --address, --lidar-mode, ...
inline std::vector<std::string> room_args(const std::string& profile = "os1-32") {
  return {"--profile", profile, "--scene", room_scene().string(), "--pose", kRoomPose, "--threads", "1"};
}

}  // namespace lidartwin::e2e
