// Trajectories: TUM files in and out, and the pose at any time (lerp + slerp between samples).
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/pose/pose.h"
#include "pose/pose_text.h"

namespace lidartwin {
namespace {

std::string format_time(double t) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.9f", t);
  return buffer;
}

void check_samples(const std::vector<StampedPose>& samples) {
  if (samples.empty()) throw InputError("trajectory: no poses");
  for (size_t i = 1; i < samples.size(); ++i) {
    if (!(samples[i].time_s > samples[i - 1].time_s)) {
      throw InputError("trajectory: timestamp " + format_time(samples[i].time_s) + " of pose " + std::to_string(i) +
                       " is not after the previous one (" + format_time(samples[i - 1].time_s) + ")");
    }
  }
}

// One TUM row "t x y z qx qy qz qw"; where = "file:line".
StampedPose parse_tum_row(std::string_view line, const std::string& where) {
  const auto values = pose_detail::parse_numbers(line);
  if (!values || values->size() != 8) {
    throw InputError(where + ": expected 8 numbers \"timestamp tx ty tz qx qy qz qw\", got \"" + std::string(line) +
                     "\"");
  }
  if (!std::isfinite((*values)[0])) throw InputError(where + ": timestamp must be finite");
  return {(*values)[0], pose_detail::pose_from_numbers(values->data() + 1, where)};
}

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

Pose interpolate(const StampedPose& a, const StampedPose& b, double time_s) {
  const double u = (time_s - a.time_s) / (b.time_s - a.time_s);
  Pose pose;
  pose.translation = (1.0 - u) * a.pose.translation + u * b.pose.translation;
  pose.rotation = a.pose.rotation.slerp(u, b.pose.rotation);  // Eigen takes the shorter arc
  return pose;
}

}  // namespace

Trajectory::Trajectory(std::vector<StampedPose> samples, bool loop) : samples_(std::move(samples)), loop_(loop) {
  check_samples(samples_);
}

Trajectory Trajectory::constant(const Pose& pose) { return Trajectory({StampedPose{0.0, pose}}, false); }

Trajectory Trajectory::load_tum(const std::filesystem::path& path, bool loop) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open trajectory file");
  std::vector<StampedPose> samples;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const std::string_view row = trim(line);
    if (row.empty() || row.front() == '#') continue;
    const std::string where = path.string() + ":" + std::to_string(number);
    StampedPose sample = parse_tum_row(row, where);
    if (!samples.empty() && !(sample.time_s > samples.back().time_s)) {
      throw InputError(where + ": timestamp " + format_time(sample.time_s) + " is not after the previous one (" +
                       format_time(samples.back().time_s) + ")");
    }
    samples.push_back(sample);
  }
  if (samples.empty()) throw InputError(path.string() + ": no poses in trajectory file");
  return Trajectory(std::move(samples), loop);
}

double Trajectory::start_s() const { return samples_.front().time_s; }
double Trajectory::duration_s() const { return samples_.back().time_s - samples_.front().time_s; }

Pose Trajectory::at(double time_s) const {
  if (samples_.size() == 1) return samples_.front().pose;
  const double period = duration_s();
  if (loop_) time_s = start_s() + (time_s - start_s()) - period * std::floor((time_s - start_s()) / period);
  const auto after = std::upper_bound(samples_.begin(), samples_.end(), time_s,
                                      [](double t, const StampedPose& s) { return t < s.time_s; });
  if (after == samples_.begin()) return samples_.front().pose;
  if (after == samples_.end()) return samples_.back().pose;
  return interpolate(*(after - 1), *after, time_s);
}

void Trajectory::save_tum(const std::filesystem::path& path) const { write_tum(path, samples_); }

void write_tum(const std::filesystem::path& path, const std::vector<StampedPose>& poses) {
  TumWriter writer(path);
  for (const auto& [t, pose] : poses) writer.write(t, pose);
  writer.close();
}

TumWriter::TumWriter(const std::filesystem::path& path) : path_(path), file_(std::fopen(path.c_str(), "w")) {
  if (file_ == nullptr) throw InputError(path.string() + ": cannot open for writing");
  std::setvbuf(file_, nullptr, _IOFBF, 1 << 16);  // `record` writes a row per column
  std::fprintf(file_, "# timestamp tx ty tz qx qy qz qw\n");
}

TumWriter::~TumWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

namespace {

// value with `decimals` digits after the point, the digits printf's "%.*f" gives (the exact binary
// value rounded to nearest, ties to even). Where value * 10^decimals is below 2^53 that is an
// integer rounding: the product's rounding error is recovered exactly with an FMA (10^decimals is
// exact), so the integer nearest the exact product is found without big-number arithmetic; larger
// values go through std::to_chars. libstdc++'s fixed-precision to_chars took 3 % of `record`'s
// CPU from the drone's pose (a row per column, 8 numbers): this takes about a tenth of that.
// n in decimal, zero-padded to at least `width` digits, two digits at a time.
char* put_digits(char* out, uint64_t n, int width) {
  static constexpr char kPairs[] =
      "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
      "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
      "8081828384858687888990919293949596979899";
  char reversed[24];
  int count = 0;
  for (; n >= 10; n /= 100, count += 2) {
    const auto pair = static_cast<size_t>(n % 100) * 2;
    reversed[count] = kPairs[pair + 1];
    reversed[count + 1] = kPairs[pair];
  }
  if (n > 0) reversed[count++] = static_cast<char>('0' + n);
  while (count < width) reversed[count++] = '0';
  for (int i = count - 1; i >= 0; --i) *out++ = reversed[i];
  return out;
}

char* put_fixed(char* out, char* end, double value, int decimals) {
  static constexpr double kPowers[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12};
  static_assert(std::size(kPowers) == 13);
  const double scale = kPowers[decimals];
  const double product = std::abs(value) * scale;
  if (!(product < 0x1p53)) return std::to_chars(out, end, value, std::chars_format::fixed, decimals).ptr;
  const double error = std::fma(std::abs(value), scale, -product);  // exact product = product + error
  double nearest = std::nearbyint(product);                         // ties to even, on the rounded product
  // |product - nearest| <= 1/2 (exact), and the error is below half an ulp of the product, so it
  // decides only where the rounded product is a tie: the exact one is then past it, or a true tie.
  const double diff = product - nearest;
  if (diff == 0.5 && error > 0.0) nearest += 1.0;
  if (diff == -0.5 && error < 0.0) nearest -= 1.0;
  const auto digits = static_cast<uint64_t>(nearest);
  const auto whole = static_cast<uint64_t>(kPowers[decimals]);
  if (std::signbit(value)) *out++ = '-';  // as printf: "-0.000" for a small negative value
  out = put_digits(out, digits / whole, 1);
  if (decimals > 0) *out++ = '.';
  return put_digits(out, digits % whole, decimals);
}

}  // namespace

// The row "%.9f %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n": `record` writes a row per column, 20 k
// rows a second of an OS1 at 2048x10 (printf made that a fifth of a short record's time).
void TumWriter::write(double time_s, const Pose& pose) {
  const auto& p = pose.translation;
  const auto& q = pose.rotation;
  const std::array<double, 8> values{time_s, p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()};
  // Room for any double: 309 integer digits, sign, point and 12 decimals, and the separator.
  std::array<char, 8 * 324> row;
  char* out = row.data();
  for (size_t i = 0; i < values.size(); ++i) {
    out = put_fixed(out, row.data() + row.size(), values[i], i < 4 ? 9 : 12);
    *out++ = i + 1 < values.size() ? ' ' : '\n';
  }
  std::fwrite(row.data(), 1, static_cast<size_t>(out - row.data()), file_);
}

void TumWriter::close() {
  if (file_ == nullptr) return;
  const bool failed = std::ferror(file_) != 0;
  const bool closed = std::fclose(file_) == 0;
  file_ = nullptr;
  if (!closed || failed) throw InputError(path_.string() + ": write failed");
}

}  // namespace lidartwin
