// A capture's returns as points, and the way from a point back to the pixels that saw it.
#include "analysis/capture_points.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "lidartwin/caster/beam_geometry.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin::analysis_detail {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

// a - b wrapped into [-pi, pi). For angles within [-pi, pi] (atan2's) the fmod is one subtraction
// or none: exact (Sterbenz) as fmod is, and the projection runs for every point of every frame.
double angle_difference(double a, double b) {
  double d = a - b + std::numbers::pi;
  if (d >= kTwoPi && d < 2.0 * kTwoPi) {
    d -= kTwoPi;
  } else if (!(d > -kTwoPi && d < kTwoPi)) {
    d = std::fmod(d, kTwoPi);
  }
  if (d < 0.0) d += kTwoPi;
  return d - std::numbers::pi;
}

}  // namespace

bool column_valid(const Scan& scan, int m, const LidarDataFormat& format) {
  return scan.packet_received[static_cast<size_t>(m / format.columns_per_packet)] != 0 && scan.column_valid(m);
}

float signal_gain_of(const Metadata& metadata) {
  const auto it = metadata.config_params.find("signal_multiplier");
  return it != metadata.config_params.end() && it->is_number() ? it->get<float>() : 1.0f;
}

std::vector<FramePoints> capture_points(const MeasuredCapture& capture) {
  const LidarDataFormat& format = capture.metadata.format;
  const int width = format.columns_per_frame, height = format.pixels_per_column;
  const BeamGeometry geometry(capture.metadata.beams, width);
  std::vector<FramePoints> frames;
  frames.reserve(capture.frames.size());
  for (const BatchedFrame& batched : capture.frames) {
    const Scan& scan = batched.scan;
    FramePoints f;
    f.width = width;
    f.height = height;
    const size_t n = static_cast<size_t>(width) * static_cast<size_t>(height);
    f.sensor.assign(n, Eigen::Vector3f::Zero());
    f.range_m.assign(n, 0.0f);
    f.column_time_s.assign(static_cast<size_t>(width), std::numeric_limits<double>::quiet_NaN());
    f.start_s = std::numeric_limits<double>::infinity();
    f.end_s = -std::numeric_limits<double>::infinity();
    for (int m = 0; m < width; ++m) {
      if (!column_valid(scan, m, format)) continue;
      const double t = static_cast<double>(scan.timestamp_ns[static_cast<size_t>(m)]) * 1e-9;
      f.column_time_s[static_cast<size_t>(m)] = t;
      f.start_s = std::min(f.start_s, t);
      f.end_s = std::max(f.end_s, t);
      for (int r = 0; r < height; ++r) {
        const uint32_t mm = scan.at(ChannelField::kRange, m, r);
        if (mm == 0) continue;
        const size_t i = f.index(m, r);
        f.range_m[i] = static_cast<float>(mm) * 0.001f;
        f.sensor[i] = geometry.point(r, m, static_cast<double>(mm)).cast<float>();
      }
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

void place(FramePoints& frame, const PoseSource& poses, double time_offset_s) {
  frame.rotation.assign(static_cast<size_t>(frame.width), Eigen::Matrix3f::Identity());
  frame.translation.assign(static_cast<size_t>(frame.width), Eigen::Vector3f::Zero());
  frame.world.assign(frame.sensor.size(), Eigen::Vector3f::Zero());
  for (int m = 0; m < frame.width; ++m) {
    const double t = frame.column_time_s[static_cast<size_t>(m)];
    if (std::isnan(t)) continue;
    const Pose pose = poses.at(t + time_offset_s);
    const Eigen::Matrix3f rotation = pose.rotation.toRotationMatrix().cast<float>();
    const Eigen::Vector3f translation = pose.translation.cast<float>();
    frame.rotation[static_cast<size_t>(m)] = rotation;
    frame.translation[static_cast<size_t>(m)] = translation;
    for (int r = 0; r < frame.height; ++r) {
      const size_t i = frame.index(m, r);
      if (frame.returned(i)) frame.world[i] = rotation * frame.sensor[i] + translation;
    }
  }
}

BeamProjector::BeamProjector(const Metadata& metadata)
    : width_(metadata.format.columns_per_frame), height_(metadata.format.pixels_per_column) {
  const size_t n = static_cast<size_t>(width_) * static_cast<size_t>(height_);
  direction_.resize(n);
  origin_.resize(n);
  for (int m = 0; m < width_; ++m) {
    for (int r = 0; r < height_; ++r) {
      const SdkLutEntry entry = sdk_lut_entry(metadata.beams, width_, r, m);
      direction_[index(m, r)] = entry.direction.normalized().cast<float>();
      origin_[index(m, r)] = entry.origin_m.cast<float>();
    }
  }
  for (int r = 0; r < height_; ++r) {
    const Eigen::Vector3f& d = direction_[index(0, r)];
    elevation_.push_back(std::atan2(static_cast<double>(d.z()), std::hypot(d.x(), d.y())));
    azimuth0_.push_back(std::atan2(static_cast<double>(d.y()), static_cast<double>(d.x())));
  }
  const Eigen::Vector3f& d1 = direction_[index(std::min(1, width_ - 1), 0)];
  step_ = width_ > 1
              ? angle_difference(std::atan2(static_cast<double>(d1.y()), static_cast<double>(d1.x())), azimuth0_[0])
              : kTwoPi;
  column_spacing_ = std::abs(step_);
  for (int r = 0; r < height_; ++r) {
    shift_.push_back(
        static_cast<int>(std::lround(angle_difference(azimuth0_[static_cast<size_t>(r)], azimuth0_[0]) / step_)));
  }
  rows_by_elevation_.resize(static_cast<size_t>(height_));
  for (int r = 0; r < height_; ++r) rows_by_elevation_[static_cast<size_t>(r)] = r;
  std::sort(rows_by_elevation_.begin(), rows_by_elevation_.end(),
            [&](int a, int b) { return elevation_[static_cast<size_t>(a)] < elevation_[static_cast<size_t>(b)]; });
  for (const int r : rows_by_elevation_) sorted_elevation_.push_back(elevation_[static_cast<size_t>(r)]);
  row_spacing_ = height_ > 1 ? (sorted_elevation_.back() - sorted_elevation_.front()) / (height_ - 1) : column_spacing_;
}

BeamProjector::Pixel BeamProjector::from_angles(double azimuth, double elevation) const {
  auto it = std::lower_bound(sorted_elevation_.begin(), sorted_elevation_.end(), elevation);
  if (it == sorted_elevation_.end() || (it != sorted_elevation_.begin() && elevation - *(it - 1) < *it - elevation)) {
    --it;
  }
  const int r = rows_by_elevation_[static_cast<size_t>(it - sorted_elevation_.begin())];
  const double steps = angle_difference(azimuth, azimuth0_[static_cast<size_t>(r)]) / step_;
  // Within half a turn of measurement id 0: wrapped by an addition, not a division (a modulo only
  // for what lies farther, which no finite point does).
  int m = static_cast<int>(std::lround(steps));
  if (m < 0) m += width_;
  if (m < 0 || m >= width_) {
    m %= width_;
    if (m < 0) m += width_;
  }
  return {m, r};
}

double projection_atan2(double y, double x) {
  // Abramowitz and Stegun 4.4.49: atan(t) on [0, 1] to within 2e-8 rad, a thousandth of a
  // microradian against pixels 6 mrad apart; folded to the other octants exactly.
  const double ax = std::abs(x), ay = std::abs(y);
  const bool steep = ay > ax;
  const double t = steep ? (ax / ay) : (ay > 0.0 ? ay / ax : 0.0);
  const double t2 = t * t;
  double a = 0.0028662257;
  for (const double c :
       {-0.0161657367, 0.0429096138, -0.0752896400, 0.1065626393, -0.1420889944, 0.1999355085, -0.3333314528, 1.0}) {
    a = a * t2 + c;
  }
  a *= t;
  if (steep) a = 0.5 * kPi - a;
  if (x < 0.0) a = kPi - a;
  return y < 0.0 ? -a : a;
}

// The projection runs for every point of every frame, in the registration and the map: libm's
// atan2 was a tenth of compare --map's time. projection_atan2 is as exact at these scales, and the
// same on every CPU (libm's picks an FMA variant where it can).
BeamProjector::Pixel BeamProjector::project(const Eigen::Vector3f& p) const {
  const auto angles = [](const Eigen::Vector3f& v) {
    const double x = v.x(), y = v.y(), z = v.z();
    return std::pair{projection_atan2(y, x), projection_atan2(z, std::sqrt(x * x + y * y))};
  };
  auto [azimuth, elevation] = angles(p);
  Pixel pixel = from_angles(azimuth, elevation);
  // Seen from the beam's own origin, not the sensor frame's.
  std::tie(azimuth, elevation) = angles(p - origin_[index(pixel.m, pixel.r)]);
  return from_angles(azimuth, elevation);
}

BeamProjector::Pixel BeamProjector::project_world(const FramePoints& frame, const Eigen::Vector3f& x) const {
  // The column it lands in decides the pose: start from the frame's middle column, then once more
  // from the column found (the sensor moves a few centimetres per column at most).
  int m = frame.width / 2;
  for (int pass = 0; pass < 2; ++pass) {
    int valid = m;
    for (int k = 0; k < frame.width && std::isnan(frame.column_time_s[static_cast<size_t>(valid)]); ++k) {
      valid = (m + k) % frame.width;
    }
    const auto c = static_cast<size_t>(valid);
    const Eigen::Vector3f sensor = frame.rotation[c].transpose() * (x - frame.translation[c]);
    const Pixel pixel = project(sensor);
    if (pass == 1 || pixel.m == m) return pixel;
    m = pixel.m;
  }
  return {m, 0};  // not reached
}

}  // namespace lidartwin::analysis_detail
