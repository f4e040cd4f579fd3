#pragma once
// Plots come from Python scripts under tools/ (Debian's python3 with numpy and matplotlib,
// DESIGN.md), run on an output directory. The C++ side only says what happened.
#include <filesystem>
#include <string>

namespace lidartwin::cli {

// Runs tools/<script> DIR; returns "wrote DIR/<product>" or why not (no script, no Python, a
// failure whose output is kept in DIR/plots.log).
std::string run_plot_script(const std::string& script, const std::filesystem::path& out, const std::string& product);

}  // namespace lidartwin::cli
