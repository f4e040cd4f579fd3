#pragma once
// What an OSF recording holds, for pcap-info: its streams, its sensor, and its lidar scans as the
// analysis reads them. Pure: no printing.
#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/pcap/osf.h"

namespace lidartwin::cli {

struct OsfSummary {
  OsfFileInfo file;
  Metadata metadata;  // the file's, or the --metadata that replaces it
  size_t scans = 0;
  uint32_t first_frame_id = 0, last_frame_id = 0;
  uint64_t first_column_ns = 0, last_column_ns = 0;  // column timestamps of valid columns
  size_t min_valid_columns = 0, max_valid_columns = 0;
  uint64_t pixels = 0;   // pixels of valid columns
  uint64_t returns = 0;  // ... whose first range is non-zero
};

// Throws InputError as OsfReader and read_capture do.
OsfSummary summarize_osf(const std::filesystem::path& osf, const std::filesystem::path& metadata_path);

}  // namespace lidartwin::cli
