#pragma once
// What `compare` writes: DIR/report.json (schema: docs/compare-report.md) and DIR/pixels.npz.
#include <filesystem>

#include <nlohmann/json.hpp>

#include "lidartwin/analysis/misfit.h"
#include "lidartwin/analysis/pixel_table.h"

namespace lidartwin {

inline constexpr const char* kCompareReportSchema = "lidartwin.compare/1";

// inputs: what was compared (paths, pose offset, profile name…), copied into the report as given.
nlohmann::json compare_report(const Misfit& misfit, const nlohmann::json& inputs, double alpha);

// Every column of the table and of the scores, one array each (names: docs/compare-report.md).
void write_pixels_npz(const std::filesystem::path& path, const PixelTable& table, const PixelScores& scores);

}  // namespace lidartwin
