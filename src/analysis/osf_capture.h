#pragma once
// An OSF recording as the analysis reads it: its LidarScans as the frames the packet path batches.
#include <cstddef>
#include <filesystem>

#include "lidartwin/analysis/measured_capture.h"

namespace lidartwin::analysis_detail {

// metadata_path empty: the sensor metadata the file carries. See read_capture for the rest.
MeasuredCapture read_osf_capture(const std::filesystem::path& osf, const std::filesystem::path& metadata_path,
                                 size_t max_frames, size_t skip_frames);

}  // namespace lidartwin::analysis_detail
