// Trajectories: TUM files in and out, and the pose at any time (lerp + slerp between samples).
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/pose/pose.h"
#include "lidartwin/pose/pose_source.h"
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
  std::fwrite(kTumHeader.data(), 1, kTumHeader.size(), file_);
}

TumWriter::~TumWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

namespace {

constexpr char kPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

// Four digits of v (< 10000) as two pairs from the table.
void put_four(char* at, uint64_t v) {
  std::memcpy(at, &kPairs[v / 100 * 2], 2);
  std::memcpy(at + 2, &kPairs[v % 100 * 2], 2);
}

// n < 10^kDigits with exactly kDigits digits (9 or 12: TUM's decimals). Each group of four comes
// from n by its own division by a constant: independent multiplications, where a digit-by-digit
// chain of divisions (or one by a table's power of ten, a hardware divide) made the row slow.
template <int kDigits>
char* put_fraction(char* out, uint64_t n) {
  static_assert(kDigits == 9 || kDigits == 12);
  if constexpr (kDigits == 12) {
    put_four(out, n / 100000000);
  } else {
    *out = static_cast<char>('0' + n / 100000000);
  }
  char* tail = out + (kDigits - 8);
  put_four(tail, n / 10000 % 10000);
  put_four(tail + 4, n % 10000);
  return out + kDigits;
}

// n in decimal, without leading zeros (an integer part: a few digits).
char* put_integer(char* out, uint64_t n) {
  char reversed[20];
  int count = 0;
  do {
    reversed[count++] = static_cast<char>('0' + n % 10);
    n /= 10;
  } while (n > 0);
  while (count > 0) *out++ = reversed[--count];
  return out;
}

// value with kDecimals (9 or 12) digits after the point, the digits printf's "%.*f" gives: the
// exact binary value rounded to nearest, ties to even. value = m 2^k exactly (m the 53-bit
// significand), so value 10^d = (m 5^d) 2^(k + d), and m 5^d < 2^81 is exact in 128-bit integers: the rounding
// is a shift with the bits shifted out as the remainder. Values whose scaled magnitude reaches
// 2^62 (or are not finite) go through std::to_chars. libstdc++'s fixed-precision to_chars took 3 %
// of `record`'s CPU from the drone's pose (a row per column, 8 numbers); this takes a fraction
// (and no FMA or rounding instruction, which this module's baseline x86-64 would call libm for).
template <int kDecimals>
char* put_fixed(char* out, char* end, double value) {
  __extension__ typedef unsigned __int128 Wide;  // GCC and Clang (-Wpedantic wants the marker)
  constexpr uint64_t kFive = kDecimals == 12 ? 244140625ULL : 1953125ULL;          // 5^d
  constexpr uint64_t kScale = kDecimals == 12 ? 1000000000000ULL : 1000000000ULL;  // 10^d
  if (!(std::abs(value) * static_cast<double>(kScale) < 0x1p62)) {
    return std::to_chars(out, end, value, std::chars_format::fixed, kDecimals).ptr;
  }
  const uint64_t bits = std::bit_cast<uint64_t>(value);
  const auto exponent = static_cast<int>((bits >> 52) & 0x7FF);
  const uint64_t fraction = bits & ((uint64_t{1} << 52) - 1);
  const uint64_t m = exponent == 0 ? fraction : fraction | (uint64_t{1} << 52);  // subnormal: no hidden bit
  const int shift = (exponent == 0 ? -1074 : exponent - 1075) + kDecimals;       // value 10^d = x 2^shift
  const Wide x = static_cast<Wide>(m) * kFive;
  uint64_t digits = 0;
  if (shift >= 0) {
    digits = static_cast<uint64_t>(x << shift);  // below 2^62 by the check above
  } else if (shift > -128) {
    const int right = -shift;
    const Wide quotient = x >> right;
    const Wide rest = x - (quotient << right);
    const Wide half = Wide{1} << (right - 1);
    digits = static_cast<uint64_t>(quotient);
    if (rest > half || (rest == half && (digits & 1) != 0)) ++digits;
  }                                       // else: below 2^-47 of a unit in the last place, rounds to 0
  if (std::signbit(value)) *out++ = '-';  // as printf: "-0.000" for a small negative value
  out = put_integer(out, digits / kScale);
  *out++ = '.';
  return put_fraction<kDecimals>(out, digits % kScale);
}

}  // namespace

// `record` writes a row per column, 20 k rows a second of an OS1 at 2048x10 (printf made that a
// fifth of a short record's time).
TumRow tum_row(double time_s, const Pose& pose) {
  const auto& p = pose.translation;
  const auto& q = pose.rotation;
  const std::array<double, 8> values{time_s, p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()};
  TumRow row;
  char* out = row.text.data();
  for (size_t i = 0; i < values.size(); ++i) {
    const auto end = row.text.data() + row.text.size();
    out = i < 4 ? put_fixed<9>(out, end, values[i]) : put_fixed<12>(out, end, values[i]);
    *out++ = i + 1 < values.size() ? ' ' : '\n';
  }
  row.size = static_cast<size_t>(out - row.text.data());
  return row;
}

void TumWriter::write(double time_s, const Pose& pose) {
  const TumRow row = tum_row(time_s, pose);
  std::fwrite(row.text.data(), 1, row.size, file_);
}

void TumWriter::close() {
  if (file_ == nullptr) return;
  const bool failed = std::ferror(file_) != 0;
  const bool closed = std::fclose(file_) == 0;
  file_ = nullptr;
  if (!closed || failed) throw InputError(path_.string() + ": write failed");
}

}  // namespace lidartwin

namespace lidartwin {

bool TrajectoryPoses::constant() const {
  const std::vector<StampedPose>& samples = trajectory_.samples();
  return std::all_of(samples.begin(), samples.end(), [&](const StampedPose& s) {
    return s.pose.translation == samples.front().pose.translation &&
           s.pose.rotation.coeffs() == samples.front().pose.rotation.coeffs();
  });
}

}  // namespace lidartwin
