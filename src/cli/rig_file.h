#pragma once
// `serve --rig FILE`: the sensors of a vehicle, run by one process (docs/rig.md). Each entry of the
// file becomes the flags of one virtual sensor: the command line's, with the sensor's own identity,
// address, profile, mounting and wire format in place of the single-sensor flags. The scene, the
// motion (trajectory, live poses, lock-step), the worker pool and the time base are the rig's.
#include <filesystem>
#include <string>
#include <vector>

#include "cli/serve_inputs.h"

namespace lidartwin::cli {

struct RigSensor {
  std::string name;  // as the file names it, for messages and logs
  ServeFlags flags;  // the command line's, with the sensor's keys applied
};

// The flags serve takes from the rig file instead: giving one of them with --rig is an error.
const std::vector<std::string>& per_sensor_flags();

// Reads the rig file. Paths in it (profiles given as files, state files, record directories) are
// relative to the file's directory. Throws InputError naming the file, the sensor (by index and
// name) and the key for every problem: unknown keys, missing ones, values out of range, two
// sensors on one address and port, two sensors with one serial number.
std::vector<RigSensor> load_rig(const std::filesystem::path& file, const ServeFlags& command_line);

}  // namespace lidartwin::cli
