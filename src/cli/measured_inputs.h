#pragma once
// What `compare` and `fit` share: the flags naming a measured capture and where it was taken, and
// turning them into the pixel table (the capture beside the scene, or static mode without one).
#include <chrono>
#include <filesystem>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "lidartwin/analysis/compare_report.h"
#include "lidartwin/analysis/frame_registration.h"
#include "lidartwin/analysis/map_table.h"
#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/analysis/pixel_table.h"
#include "lidartwin/analysis/pose_refinement.h"
#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin::cli {

struct MeasuredFlags {
  std::string capture;  // a pcap, or a `record` output directory
  std::string metadata;
  std::string scene;
  std::string pose;
  double time_offset_s = 0.0;
  size_t frames = 0;
  size_t skip_frames = 0;
  int threads = 0;
  bool static_mode = false;
  bool map_mode = false;
  bool within_frame = false;  // --map: references from each frame's own returns (also for a one-frame capture)
  bool refine_pose = false;
};

// --capture, --metadata, --scene, --pose, --time-offset, --frames, --skip-frames, --threads,
// --refine-pose, --static, --map and --within-frame.
void add_measured_options(CLI::App* sub, MeasuredFlags& flags);

// The steps on stderr: on a terminal one line per step ("reading the capture ... 0.1 s"), a bar
// while casting; in a log plain lines (the step as it starts, each quarter of a bar, the step's
// time), so a log shows what a long step is doing.
class Steps {
 public:
  Steps();
  void start(const char* what);
  void progress(const char* what, double fraction) const;
  // Within a step: what it does now ("diagnosing: fitting incidence (E4), 3 of 8").
  void note(const std::string& what) const;
  void done() const;

 private:
  bool tty_;
  std::string what_;
  mutable int printed_quarter_ = 0;
  std::chrono::steady_clock::time_point started_;
};

// The capture, its pixel table and what was compared (with --refine-pose the correction, with --map
// the registration and what was left out). Throws InputError for every input that does not fit
// (see compare's tests).
struct Measured {
  MeasuredCapture capture;
  PixelTable table;
  CompareInputs inputs;  // but its profile and seed, which are the command's
};
Measured measure(const MeasuredFlags& flags, const SensorProfile& profile, const EffectChain& chain, Steps& steps);

}  // namespace lidartwin::cli
