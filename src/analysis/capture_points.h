#pragma once
// A capture's returns as points, for what the analysis does without a scene (frame registration,
// map mode): each frame a grid of its pixels' points in the sensor frame (the SDK's XYZ, protocol
// doc 7.1), placed in the world by the pose of the pixel's own column, and the way back from a
// world point to the pixels of a frame that looked at it (BeamProjector), so that neighbours across
// frames are found through the frames' own grids, at any range, without a search structure.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/pose/pose_source.h"

namespace lidartwin::analysis_detail {

// One frame's returns. Pixel (measurement id m, row r) is element m * height + r.
struct FramePoints {
  int width = 0, height = 0;
  std::vector<Eigen::Vector3f> sensor;       // the SDK's point, sensor frame, metres
  std::vector<float> range_m;                // 0: no return, or its column is not valid
  std::vector<double> column_time_s;         // [width], capture clock; NaN where the column is not valid
  std::vector<Eigen::Vector3f> world;        // sensor points placed by their columns' poses (place())
  std::vector<Eigen::Matrix3f> rotation;     // [width], world_from_sensor of each column
  std::vector<Eigen::Vector3f> translation;  // [width]
  double start_s = 0.0, end_s = 0.0;         // first and last valid column times
  size_t index(int m, int r) const {
    return static_cast<size_t>(m) * static_cast<size_t>(height) + static_cast<size_t>(r);
  }
  bool returned(size_t i) const { return range_m[i] > 0.0f; }
};

// Whether column m of a scan was measured: its packet arrived and its status says valid (LEGACY:
// all ones).
bool column_valid(const Scan& scan, int m, const LidarDataFormat& format);

// signal_multiplier scales SIGNAL as the sensor's config says (protocol doc 3.5); 1 when absent.
float signal_gain_of(const Metadata& metadata);

// Every frame of the capture, unplaced (world empty). Columns whose status is not valid, or whose
// packet never arrived, hold no returns.
std::vector<FramePoints> capture_points(const MeasuredCapture& capture);

// Places a frame's points in the world: each column by poses.at(its time + time_offset_s).
void place(FramePoints& frame, const PoseSource& poses, double time_offset_s = 0.0);

// atan2 as the projection computes it: within 2e-8 rad of std::atan2, fast, and the same on every
// CPU.
double projection_atan2(double y, double x);

// From a point in a frame's sensor frame back to the pixel whose beam passes nearest: the row
// whose elevation is nearest, the measurement id whose azimuth (with the row's own azimuth offset)
// is nearest. The beams' origins (a few centimetres off the sensor's) are allowed for by one
// refinement. Exact enough to seed a search of a few pixels around it.
class BeamProjector {
 public:
  BeamProjector(const Metadata& metadata);
  struct Pixel {
    int m = 0, r = 0;
  };
  Pixel project(const Eigen::Vector3f& sensor_point) const;
  // A world point's pixel in a placed frame, through the pose of the column it lands in.
  Pixel project_world(const FramePoints& frame, const Eigen::Vector3f& world_point) const;
  // The pixel dr rows and dm columns from (m, r) in azimuth, not in measurement id: rows look at
  // their own azimuth offsets (an OS1-128's consecutive rows up to 8.4 degrees apart, protocol doc
  // 3.4), so the same measurement id of the next row is not the pixel beside. None past the rows.
  std::optional<Pixel> beside(int m, int r, int dm, int dr) const {
    const int rr = r + dr;
    if (rr < 0 || rr >= height_) return std::nullopt;
    // Wrapped by subtraction: windows reach a few dozen columns, and a modulo per pixel cost more
    // than the rest of a gather's test (map mode, registration).
    int mm = m + shift_[static_cast<size_t>(r)] - shift_[static_cast<size_t>(rr)] + dm;
    while (mm >= width_) mm -= width_;
    while (mm < 0) mm += width_;
    return Pixel{mm, rr};
  }
  // Angular spacing of neighbouring rows (mean) and columns, radians.
  double row_spacing_rad() const { return row_spacing_; }
  double column_spacing_rad() const { return column_spacing_; }
  // The beam of pixel (m, r) in the sensor frame: origin and unit direction.
  const Eigen::Vector3f& direction(int m, int r) const { return direction_[index(m, r)]; }
  const Eigen::Vector3f& origin(int m, int r) const { return origin_[index(m, r)]; }

 private:
  size_t index(int m, int r) const {
    return static_cast<size_t>(m) * static_cast<size_t>(height_) + static_cast<size_t>(r);
  }
  Pixel from_angles(double azimuth, double elevation) const;
  int width_ = 0, height_ = 0;
  std::vector<Eigen::Vector3f> direction_, origin_;  // [m * height + r]
  std::vector<double> elevation_;                    // [row]
  std::vector<int> rows_by_elevation_;               // rows, ascending elevation
  std::vector<double> sorted_elevation_;
  std::vector<double> azimuth0_;  // [row] the direction's azimuth at measurement id 0
  double step_ = 0.0;             // azimuth change per measurement id (signed)
  std::vector<int> shift_;        // [row] its azimuth offset in measurement ids (beside())
  double row_spacing_ = 0.0, column_spacing_ = 0.0;
};

}  // namespace lidartwin::analysis_detail
