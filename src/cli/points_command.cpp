// `lidartwin points`: a capture's frames as point clouds in the sensor frame, the way the SDK
// projects them (protocol doc 7.1), with each point's column timestamp, in one .npz that numpy,
// Open3D or any odometry reads without lidartwin (tools/lidar-odometry.py does).
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cli/command.h"
#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/analysis/npz_writer.h"
#include "lidartwin/caster/beam_geometry.h"

namespace lidartwin::cli {
namespace {

struct PointsFlags {
  std::string capture;
  std::string metadata;
  std::string out;
  size_t frames = 0;
};

int run_points(const PointsFlags& flags) {
  const MeasuredCapture capture = read_capture(flags.capture, flags.metadata, flags.frames);
  const LidarDataFormat& format = capture.metadata.format;
  const BeamGeometry geometry(capture.metadata.beams, format.columns_per_frame);
  std::vector<float> xyz;
  std::vector<double> times_s, frame_times_s;
  std::vector<uint32_t> frame_offsets{0}, frame_ids;
  std::vector<uint16_t> rows, columns;
  for (const BatchedFrame& frame : capture.frames) {
    const Scan& scan = frame.scan;
    double first_time_s = -1.0;
    for (int m = 0; m < scan.width; ++m) {
      const auto column = static_cast<size_t>(m);
      if (!scan.column_valid(m)) continue;
      const double time_s = static_cast<double>(scan.timestamp_ns[column]) * 1e-9;
      if (first_time_s < 0) first_time_s = time_s;
      for (int r = 0; r < scan.height; ++r) {
        const uint32_t range_mm = scan.at(ChannelField::kRange, m, r);
        if (range_mm == 0) continue;
        const Eigen::Vector3d p = geometry.point(r, m, range_mm);
        xyz.insert(xyz.end(), {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
        times_s.push_back(time_s);
        rows.push_back(static_cast<uint16_t>(r));
        columns.push_back(static_cast<uint16_t>(m));
      }
    }
    if (first_time_s < 0) continue;  // no valid column: nothing to register
    frame_times_s.push_back(first_time_s);
    frame_ids.push_back(frame.frame_id);
    frame_offsets.push_back(static_cast<uint32_t>(times_s.size()));
  }
  NpzWriter npz(flags.out);
  npz.add("xyz", xyz);
  npz.add("t_s", times_s);
  npz.add("row", rows);
  npz.add("column", columns);
  npz.add("frame_offsets", frame_offsets);
  npz.add("frame_t_s", frame_times_s);
  npz.add("frame_id", frame_ids);
  npz.close();
  std::printf("wrote %s: %zu frames, %zu points\n", flags.out.c_str(), frame_times_s.size(), times_s.size());
  return 0;
}

void setup_points(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<PointsFlags>();
  CLI::App* sub = app.add_subcommand(
      "points", "A capture's frames as XYZ points (sensor frame, as the SDK projects them) with timestamps, in .npz");
  sub->add_option("--capture", flags->capture, "pcap of the sensor's lidar packets, or an OSF recording")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--metadata", flags->metadata,
                  "the sensor's metadata JSON (optional for an OSF file, which carries it)")
      ->check(CLI::ExistingFile);
  sub->add_option("--out", flags->out,
                  "the .npz: xyz (flat, x y z of each point in turn: reshape(-1, 3); m), t_s (column timestamp, s), "
                  "row, column; per frame frame_offsets "
                  "(F + 1, into the points), frame_t_s (first valid column), frame_id")
      ->required();
  sub->add_option("--frames", flags->frames, "at most this many frames (0 = all)")->capture_default_str();
  sub->callback([&run, flags] { run = [flags] { return run_points(*flags); }; });
}

const RegisterCommand registered_points("points", setup_points);

}  // namespace
}  // namespace lidartwin::cli
