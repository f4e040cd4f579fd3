#include "cli/osf_info.h"

#include <algorithm>
#include <limits>

namespace lidartwin::cli {
OsfSummary summarize_osf(const std::filesystem::path& osf, const std::filesystem::path& metadata_path) {
  OsfSummary s;
  s.file = OsfReader(osf).info();
  MeasuredCapture capture = read_capture(osf, metadata_path);
  s.metadata = std::move(capture.metadata);
  s.scans = capture.frames.size();
  s.min_valid_columns = std::numeric_limits<size_t>::max();
  for (const BatchedFrame& frame : capture.frames) {
    const Scan& scan = frame.scan;
    if (&frame == &capture.frames.front()) s.first_frame_id = frame.frame_id;
    s.last_frame_id = frame.frame_id;
    size_t valid = 0;
    for (size_t m = 0; m < scan.status.size(); ++m) {
      if (!scan.column_valid(static_cast<int>(m))) continue;
      ++valid;
      const uint64_t t = scan.timestamp_ns[m];
      if (s.first_column_ns == 0 || t < s.first_column_ns) s.first_column_ns = t;
      s.last_column_ns = std::max(s.last_column_ns, t);
      for (const uint32_t range : scan.column(ChannelField::kRange, static_cast<int>(m))) {
        ++s.pixels;
        if (range != 0) ++s.returns;
      }
    }
    s.min_valid_columns = std::min(s.min_valid_columns, valid);
    s.max_valid_columns = std::max(s.max_valid_columns, valid);
  }
  return s;
}

}  // namespace lidartwin::cli
